"""Observed runs (DESIGN.md section 4): the JSON Lines file that diagnosis reads.

One run per line::

    {"run_id": "r1", "start_pose": [x, y, h], "gait_cycles": [12, 12, 3, ...],
     "poses": [[x, y, h], ...], "cycles_since_power_on": 0}

``poses[i]`` is the observed pose after ``gait_cycles[i]``; ``cycles_since_power_on`` (optional,
default 0) counts the gait cycles the robot executed before the run. Every problem is reported
as one line naming the file, the line, the run and the field.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pac_host.errors import InputError
from pac_host.files import read_text, write_atomic

N_IDS = 32


@dataclass(frozen=True)
class Run:
    """One observed run: commanded gait cycles and the observed pose after each."""

    run_id: str
    start_pose: np.ndarray  # (3,)
    gait_cycles: np.ndarray  # (n,) int
    poses: np.ndarray  # (n, 3)
    cycles_since_power_on: int = 0

    @property
    def n(self) -> int:
        return len(self.gait_cycles)

    def all_poses(self) -> np.ndarray:
        """Start pose then the pose after every gait cycle: (n + 1, 3)."""
        return np.vstack([self.start_pose[None], self.poses])

    def to_json(self) -> dict:
        return {
            "run_id": self.run_id,
            "start_pose": [float(v) for v in self.start_pose],
            "gait_cycles": [int(g) for g in self.gait_cycles],
            "poses": [[float(v) for v in p] for p in self.poses],
            "cycles_since_power_on": int(self.cycles_since_power_on),
        }


def _reject_constant(name: str):
    raise ValueError(f"{name} is not a number")


def _triple(v: object, where: str) -> list[float]:
    if not isinstance(v, list) or len(v) != 3:
        raise InputError(f"{where} must be a list [x, y, h]")
    out = []
    for c in v:
        if isinstance(c, bool) or not isinstance(c, int | float) or not math.isfinite(c):
            raise InputError(f"{where} must hold 3 finite numbers, got {v!r}")
        out.append(float(c))
    return out


def run_from_json(doc: object, where: str) -> Run:
    """Validate one parsed run; ``where`` names its place (file and line) in messages."""
    if not isinstance(doc, dict):
        raise InputError(f"{where}: expected a JSON object (one run per line)")
    rid = doc.get("run_id")
    if isinstance(rid, int) and not isinstance(rid, bool):
        rid = str(rid)
    if not isinstance(rid, str) or not rid:
        raise InputError(f"{where}: run_id must be a non-empty string")
    at = f"{where} (run {rid!r})"
    start = _triple(doc.get("start_pose"), f"{at}: start_pose")
    ids = doc.get("gait_cycles")
    if not isinstance(ids, list) or not ids:
        raise InputError(f"{at}: gait_cycles must be a non-empty list of gait cycle ids")
    for k, g in enumerate(ids):
        if isinstance(g, bool) or not isinstance(g, int) or not 0 <= g < N_IDS:
            raise InputError(f"{at}: gait_cycles[{k}] = {g!r} is not a gait cycle id 0..31")
    poses = doc.get("poses")
    if not isinstance(poses, list):
        raise InputError(f"{at}: poses must be a list of [x, y, h]")
    if len(poses) != len(ids):
        raise InputError(
            f"{at}: poses has {len(poses)} entries but gait_cycles has {len(ids)} "
            "(poses[i] is the pose after gait_cycles[i])"
        )
    rows = [_triple(p, f"{at}: poses[{k}]") for k, p in enumerate(poses)]
    n0 = doc.get("cycles_since_power_on", 0)
    if isinstance(n0, bool) or not isinstance(n0, int) or n0 < 0:
        raise InputError(f"{at}: cycles_since_power_on must be a non-negative integer")
    return Run(rid, np.array(start), np.array(ids, dtype=np.int64), np.array(rows), n0)


def parse_runs(lines: Iterable[str], source: str = "runs") -> list[Run]:
    """Parse JSON Lines text into runs; blank lines are skipped; run ids must be unique."""
    runs: list[Run] = []
    seen: dict[str, int] = {}
    for lineno, line in enumerate(lines, 1):
        if not line.strip():
            continue
        where = f"{source} line {lineno}"
        try:
            doc = json.loads(line, parse_constant=_reject_constant)
        except ValueError as e:
            raise InputError(f"{where}: not a JSON Lines record ({e})") from None
        run = run_from_json(doc, where)
        if run.run_id in seen:
            raise InputError(
                f"{where}: run_id {run.run_id!r} already used on line {seen[run.run_id]}"
            )
        seen[run.run_id] = lineno
        runs.append(run)
    if not runs:
        raise InputError(f"{source}: no runs found (expected one JSON object per line)")
    return runs


def read_runs(path: str | Path) -> list[Run]:
    """Read and validate an observed-runs JSON Lines file."""
    p = Path(path)
    text = read_text(p, "runs")
    return parse_runs(text.splitlines(), str(p))


def write_runs(runs: Iterable[Run], path: str | Path) -> None:
    """Write runs as JSON Lines (atomically: a crash never leaves half a file)."""
    write_atomic(path, "".join(json.dumps(r.to_json()) + "\n" for r in runs))
