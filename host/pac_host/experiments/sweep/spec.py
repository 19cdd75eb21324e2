"""The sweep file (TOML): fixed settings, a grid, and explicit cells, expanded into cells.

```toml
[settings]            # every cell's, unless the cell sets its own
seeds = 30
optimum_runs = 4

[grid]                # every combination of these values (one list per setting)
methods = ["full", "partial"]
model_fitness = ["coverage", "steps"]
actual = ["shifted", "robots/skewed.json"]      # table files relative to this file
effects = [[], ["transition:alpha=0.3"]]

[[cells]]             # added to the grid's cells
methods = "oracle"
```

``profile`` (``paper``, ``default``; ``none`` unless given: the configuration's own defaults)
is what a cell's settings start from; every cell records it.

A cell is identified by a hash of everything its results depend on (its whole config and both
tables' contents), so a resumed sweep reuses a finished cell only if it would compute the same.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from pac_host.errors import InputError
from pac_host.experiments.experiment import ExperimentConfig
from pac_host.experiments.sweep.settings import (
    NO_PROFILE,
    PROFILE,
    TABLE_SETTINGS,
    canonical_name,
    check_value,
    experiment_config,
)
from pac_host.files import read_text
from pac_host.model import GaitTable, load_with_effects
from pac_host.model.table import BUILTIN

SECTIONS = ("settings", "grid", "cells")


@dataclass(frozen=True)
class Cell:
    """One experiment of the sweep: the settings that make it, and what they resolve to."""

    index: int
    id: str
    settings: dict[str, Any]  # canonical names, JSON values
    config: ExperimentConfig
    model: GaitTable
    actual: GaitTable

    def label(self, keys: list[str]) -> str:
        """The cell's values of ``keys`` (the settings that vary), those it sets."""
        return ", ".join(f"{k}={_short(self.settings[k])}" for k in keys
                         if k in self.settings) or self.id


def _short(v: Any) -> str:
    return ";".join(map(str, v)) if isinstance(v, list) else str(v)


def _flatten(doc: dict, prefix: str = "") -> dict[str, Any]:
    """TOML's dotted keys and sub-tables (``pal.cga.elite = 3``) as dotted names."""
    out: dict[str, Any] = {}
    for k, v in doc.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, name + "."))
        else:
            out[name] = v
    return out


def _canonical(doc: dict, where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in _flatten(doc).items():
        try:
            name = canonical_name(key)
        except InputError as e:
            raise InputError(f"{where}: {e}") from None
        if name in out:
            raise InputError(f"{where}: setting {name!r} given twice")
        out[name] = value
    return out


def _checked(settings: dict[str, Any], where: str) -> dict[str, Any]:
    try:
        return {k: check_value(k, v) for k, v in settings.items()}
    except InputError as e:
        raise InputError(f"{where}: {e}") from None


def parse_sweep(doc: dict, base_dir: Path = Path("."), source: str = "sweep") -> list[Cell]:
    """The cells of a parsed sweep document, grid cells first, duplicates dropped."""
    unknown = [k for k in doc if k not in SECTIONS]
    if unknown:
        raise InputError(f"{source}: unknown section [{unknown[0]}] (sections: "
                         f"{', '.join(SECTIONS)})")
    for name, kind in (("settings", dict), ("grid", dict), ("cells", list)):
        if name in doc and not isinstance(doc[name], kind):
            raise InputError(f"{source}: {name} must be a "
                             f"{'table' if kind is dict else 'list of tables [[cells]]'}")
    fixed = _canonical(doc.get("settings", {}), f"{source} [settings]")
    combos: list[dict[str, Any]] = []
    grid = _canonical(doc.get("grid", {}), f"{source} [grid]")
    for key, values in grid.items():
        if not isinstance(values, list):
            raise InputError(f"{source} [grid]: {key} must be a list of values, got {values!r}")
        if not values:
            raise InputError(f"{source} [grid]: {key} has no values: the grid is empty")
    if grid:
        combos += [dict(zip(grid, vs, strict=True)) for vs in itertools.product(*grid.values())]
    for n, c in enumerate(doc.get("cells", []), 1):
        if not isinstance(c, dict):
            raise InputError(f"{source} [[cells]] {n}: must be a table of settings")
        combos.append(_canonical(c, f"{source} [[cells]] {n}"))
    if not combos:
        raise InputError(f"{source}: no cells: give a [grid] with values, or [[cells]]")
    cells: list[Cell] = []
    seen: set[str] = set()
    for n, combo in enumerate(combos):
        where = f"{source} cell {n + 1}"
        settings = _checked({PROFILE: NO_PROFILE, **fixed, **combo}, where)  # recorded
        cell = _resolve(len(cells), settings, base_dir, where)
        if cell.id not in seen:
            seen.add(cell.id)
            cells.append(cell)
    return cells


def load_sweep(path: Path) -> list[Cell]:
    """Read a sweep file; every problem is one :class:`InputError` naming its place."""
    text = read_text(path, "sweep file")
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{path}: not valid TOML: {e}") from None
    return parse_sweep(doc, Path(path).resolve().parent, str(path))


def _table_spec(spec: str, base_dir: Path) -> str:
    return spec if spec in BUILTIN else str(base_dir / spec)


def _resolve(index: int, settings: dict[str, Any], base_dir: Path, where: str) -> Cell:
    try:
        cfg = experiment_config(settings)
        model = load_with_effects(_table_spec(settings.get("model", TABLE_SETTINGS["model"]),
                                              base_dir))
        actual = load_with_effects(
            _table_spec(settings.get("actual", TABLE_SETTINGS["actual"]), base_dir),
            settings.get("effects", TABLE_SETTINGS["effects"]))
    except InputError as e:
        raise InputError(f"{where}: {e}") from None
    return Cell(index, cell_id(cfg, model, actual), settings, cfg, model, actual)


def cell_id(cfg: ExperimentConfig, model: GaitTable, actual: GaitTable) -> str:
    """A hash of all the cell's results depend on."""
    doc = {"config": asdict(cfg), "model": model.to_json(), "actual": actual.to_json(),
           "names": [model.name, actual.name]}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:12]
