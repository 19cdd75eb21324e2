"""Simulated actual robots beyond the paper's shifted table, for measuring how PAL learns.

The shifted robot is exactly one library effect (a turn shift), so a method could win there by
recognising it. These robots are made to be hard in different ways (docs/explanation/learning.md):

- ``noisy_rows``: an independent error on every value of every row (no structure to find);
- ``asymmetric``: left and right turns differ (right turns 25% weaker, left turns one strength
  harder), which no single library effect describes;
- ``library_on_changed``: a changed table (smaller independent row errors) with two library
  effects on top, a transition between gaits and a yaw bias;
- ``outside_library``: an effect outside the library, turning slows the stride and stretches
  the heading change more than in proportion with the turn's strength.

Each is a pure function of its seed; ``python -m pac_host.model.robots DIR`` writes them as
pac-gait-table/1 files for ``pac-host experiment --actual FILE``.

>>> t = build("asymmetric")
>>> t.rows[12].tolist() == t.rows[12].tolist(), t.name
(True, 'asymmetric')
>>> sorted(ROBOTS)
['asymmetric', 'library_on_changed', 'noisy_rows', 'outside_library']
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from pac_host.errors import InputError
from pac_host.model.effects import Effect
from pac_host.model.table import GaitTable, measured_table, save_table, strength

DEFAULT_SEED = 13


def _noisy(rows: np.ndarray, scale, seed: int) -> np.ndarray:
    return rows + np.random.default_rng(seed).normal(size=rows.shape) * np.asarray(scale)


def noisy_rows(seed: int = DEFAULT_SEED) -> GaitTable:
    return GaitTable(_noisy(measured_table().rows, (0.8, 0.5, 2.0), seed), (), "noisy_rows")


def asymmetric(seed: int = DEFAULT_SEED) -> GaitTable:
    rows = measured_table().rows.copy()
    right, left = np.arange(16), np.arange(16, 32)
    rows[right, 1:] *= 0.75
    rows[left] = rows[16 + np.clip(np.arange(16) - 1, 0, 15)]
    rows[31] = measured_table().rows[31]  # straight stays straight
    return GaitTable(rows, (), "asymmetric")


def library_on_changed(seed: int = DEFAULT_SEED) -> GaitTable:
    rows = _noisy(measured_table().rows, (0.3, 0.2, 0.8), seed + 1)
    return GaitTable(rows, (Effect("yaw_bias", {"delta": 1.0}),
                            Effect("transition", {"alpha": 0.3})), "library_on_changed")


def outside_library(seed: int = DEFAULT_SEED) -> GaitTable:
    rows = measured_table().rows.copy()
    turn = 15 - strength(np.arange(32))  # 0 straight .. 15 hardest
    rows[:, 0] *= 1.0 - 0.025 * turn
    rows[:, 2] *= 1.0 + 0.002 * turn**2
    return GaitTable(rows, (), "outside_library")


ROBOTS: dict[str, Callable[[int], GaitTable]] = {
    "noisy_rows": noisy_rows,
    "asymmetric": asymmetric,
    "library_on_changed": library_on_changed,
    "outside_library": outside_library,
}


def build(name: str, seed: int = DEFAULT_SEED) -> GaitTable:
    if name not in ROBOTS:
        raise InputError(f"unknown robot {name!r}; known: {', '.join(ROBOTS)}")
    return ROBOTS[name](seed)


def write_all(out_dir: Path, seed: int = DEFAULT_SEED) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in ROBOTS:
        path = out_dir / f"{name}.json"
        save_table(build(name, seed), path)
        paths.append(path)
    return paths


if __name__ == "__main__":  # pragma: no cover - a documented one-liner: DIR [SEED]
    for p in write_all(Path(sys.argv[1] if len(sys.argv) > 1 else "robots"),
                       int(sys.argv[2]) if len(sys.argv) > 2 else DEFAULT_SEED):
        print(p)
