"""Gait tables: the paper's Figure 2, the shifted "actual robot", and the pac-gait-table/1 format.

A gait cycle id is ``side << 4 | strength`` (side 0 = right turn, 1 = left; strength 0 = hardest
turn, 15 = straight). A table maps each of the 32 ids to (F, T, dH): cm forward, cm lateral (right
positive) and degrees of heading change (right positive) over one gait cycle.

>>> t = measured_table()
>>> t.rows[12].tolist()
[12.1, -0.1, 0.0]
>>> shifted_table().rows[0].tolist() == measured_table().rows[1].tolist()
True
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pac_host.errors import InputError
from pac_host.files import read_text, write_atomic
from pac_host.model.step_noise import NONE, StepNoise, parse_step_noise, step_noise_from_json

FORMAT = "pac-gait-table/1"
N_IDS = 32
COMPONENTS = ("F", "T", "dH")

# Figure 2 of the paper: (F cm, T cm, dH deg) for ids 0..31.
_FIGURE_2 = (
    (3.7, 4.0, 24.3), (3.7, 4.0, 22.2), (3.8, 4.3, 20.2), (4.8, 4.3, 18.8),
    (5.3, 4.0, 16.7), (6.5, 4.0, 14.7), (7.3, 3.8, 13.2), (8.1, 3.5, 12.2),
    (8.4, 3.5, 11.0), (9.4, 2.8, 8.3), (10.1, 2.3, 6.2), (11.4, 0.8, 2.7),
    (12.1, -0.1, 0.0), (12.1, -0.5, -1.3), (12.4, -0.5, -1.8), (11.6, -0.8, -1.3),
    (5.0, -3.7, -26.7), (5.7, -3.7, -24.7), (6.0, -5.0, -22.2), (6.3, -4.8, -20.3),
    (7.3, -4.3, -18.8), (8.4, -4.3, -15.8), (9.6, -3.8, -13.5), (10.4, -2.8, -10.3),
    (11.1, -2.3, -7.0), (11.9, -1.5, -5.0), (12.1, -1.5, -3.7), (12.1, -1.0, -2.7),
    (12.4, -1.0, -2.3), (12.1, -1.0, -2.7), (12.1, -1.3, -2.3), (11.6, -0.8, -1.3),
)


def side(gait_id: int | np.ndarray) -> int | np.ndarray:
    """Turn side of a gait cycle id: 0 = right, 1 = left."""
    return gait_id >> 4


def strength(gait_id: int | np.ndarray) -> int | np.ndarray:
    """Turn strength of a gait cycle id: 0 = hardest turn, 15 = straight."""
    return gait_id & 15


@dataclass(frozen=True)
class GaitTable:
    """A gait table (32 x 3 float array) plus the unmodelled effects the robot also shows, and
    its step noise (:mod:`pac_host.model.step_noise`; none by default)."""

    rows: np.ndarray
    effects: tuple = field(default=())
    name: str = "table"
    step_noise: StepNoise = NONE

    def __post_init__(self) -> None:
        rows = np.array(self.rows, dtype=np.float64)
        if rows.shape != (N_IDS, 3):
            raise InputError(f"gait table {self.name!r}: expected 32 x 3 rows, got {rows.shape}")
        if not np.all(np.isfinite(rows)):
            raise InputError(f"gait table {self.name!r}: rows contain NaN or infinity")
        rows.setflags(write=False)
        object.__setattr__(self, "rows", rows)
        object.__setattr__(self, "effects", tuple(self.effects))

    def with_rows(self, rows: np.ndarray, name: str | None = None) -> GaitTable:
        return GaitTable(rows, self.effects, name or self.name, self.step_noise)

    def with_effects(self, effects, name: str | None = None) -> GaitTable:
        return GaitTable(self.rows, tuple(effects), name or self.name, self.step_noise)

    def with_step_noise(self, noise: StepNoise) -> GaitTable:
        return GaitTable(self.rows, self.effects, self.name, noise)

    def to_json(self) -> dict:
        doc: dict = {
            "format": FORMAT,
            "cycles": [
                {"id": i, "F": float(f), "T": float(t), "dH": float(h)}
                for i, (f, t, h) in enumerate(self.rows.tolist())
            ],
        }
        if self.effects:
            doc["effects"] = [e.to_json() for e in self.effects]
        if not self.step_noise.is_zero():
            doc["step_noise"] = self.step_noise.to_json()
        return doc


def measured_table() -> GaitTable:
    """The paper's measured table (Figure 2): the model the CGA starts from."""
    return GaitTable(np.array(_FIGURE_2), name="measured")


def shifted_table() -> GaitTable:
    """The paper's simulated actual robot: every turn one strength weaker, straights unchanged."""
    m = np.array(_FIGURE_2)
    rows = m.copy()
    for s in (0, 1):
        base = s << 4
        rows[base : base + 15] = m[base + 1 : base + 16]
    return GaitTable(rows, name="shifted")


BUILTIN = {"measured": measured_table, "shifted": shifted_table}


def table_from_json(doc: object, source: str = "table") -> GaitTable:
    """Validate a parsed pac-gait-table/1 document; every problem names its place."""
    from pac_host.model.effects import effect_from_json

    if not isinstance(doc, dict):
        raise InputError(f"{source}: expected a JSON object with 'format' and 'cycles'")
    if doc.get("format") != FORMAT:
        raise InputError(f"{source}: 'format' must be {FORMAT!r}, got {doc.get('format')!r}")
    cycles = doc.get("cycles")
    if not isinstance(cycles, list):
        raise InputError(f"{source}: 'cycles' must be a list of 32 objects")
    rows = np.full((N_IDS, 3), np.nan)
    seen: set[int] = set()
    for k, c in enumerate(cycles):
        if not isinstance(c, dict):
            raise InputError(f"{source}: cycles[{k}] is not an object")
        gid = c.get("id")
        if not isinstance(gid, int) or isinstance(gid, bool) or not 0 <= gid < N_IDS:
            raise InputError(f"{source}: cycles[{k}].id must be an integer 0..31, got {gid!r}")
        if gid in seen:
            raise InputError(f"{source}: gait cycle id {gid} appears twice")
        seen.add(gid)
        for j, comp in enumerate(COMPONENTS):
            v = c.get(comp)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise InputError(f"{source}: cycles[{k}] (id {gid}).{comp} must be a finite number")
            rows[gid, j] = float(v)
    missing = sorted(set(range(N_IDS)) - seen)
    if missing:
        raise InputError(f"{source}: gait cycle ids missing: {missing}")
    effects = doc.get("effects", [])
    if not isinstance(effects, list):
        raise InputError(f"{source}: 'effects' must be a list")
    effs = tuple(effect_from_json(e, f"{source}: effects[{k}]") for k, e in enumerate(effects))
    noise = (step_noise_from_json(doc["step_noise"], f"{source}: step_noise")
             if "step_noise" in doc else NONE)
    return GaitTable(rows, effs, name=Path(source).stem, step_noise=noise)


def load_table(path: str | Path) -> GaitTable:
    """Read and validate a pac-gait-table/1 JSON file."""
    p = Path(path)
    text = read_text(p, "gait table")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"{p}: not valid JSON (line {e.lineno}: {e.msg})") from None
    return table_from_json(doc, str(p))


def save_table(table: GaitTable, path: str | Path) -> None:
    """Write a table as pac-gait-table/1 (atomically: a crash never leaves half a file)."""
    write_atomic(path, json.dumps(table.to_json(), indent=1) + "\n")


def resolve_table(spec: str) -> GaitTable:
    """A built-in table name (``measured``, ``shifted``) or a path to a table file."""
    if spec in BUILTIN:
        return BUILTIN[spec]()
    return load_table(spec)


def load_with_effects(table_spec: str, effect_specs: Sequence[str] = (),
                      step_noise: str | None = None) -> GaitTable:
    """Resolve a table and add effects given as ``name:param=value,...`` to the table's own;
    ``step_noise`` (``CM,DEG`` or ``none``), when given, replaces the table's."""
    from pac_host.model.effects import parse_effect

    table = resolve_table(table_spec)
    extra = [parse_effect(s) for s in effect_specs]
    names = [e.name for e in table.effects] + [e.name for e in extra]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise InputError(f"effect {sorted(dup)[0]} given twice")
    if step_noise is not None:
        table = table.with_step_noise(parse_step_noise(step_noise))
    return table.with_effects(tuple(table.effects) + tuple(extra)) if extra else table
