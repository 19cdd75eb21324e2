"""The best turn cycles known on the built-in robots (``best_known.json`` beside this module):
the measured and shifted tables and the robots of :mod:`pac_host.model.robots`, at the budget
the file names, from the start pose of DESIGN.md. Each is what a search found and
``pac-host simulate`` verifies (the tests simulate every record); an experiment on one of these
robots measures against its record, never only against its own (shorter) optimum.

>>> fitness("shifted") >= 49, fitness("nobody") is None
(True, True)
>>> from pac_host.model import shifted_table
>>> name, rec = for_table(shifted_table(), budget())
>>> name, rec["fitness"] >= 49, for_table(shifted_table(), 100)
('shifted', True, None)

A robot with step noise is measured against the record's robust entry at that noise (the
best known mean fitness over noisy walks), not the noise-free fitness no walk repeats:

>>> from pac_host.model.step_noise import parse_step_noise
>>> noisy = shifted_table().with_step_noise(parse_step_noise("0.3,1"))
>>> name, rec = robust_for_table(noisy, budget())
>>> name, rec["step_noise"], rec["mean"] >= 24
('shifted', '0.3,1', True)
>>> robust_for_table(shifted_table().with_step_noise(parse_step_noise("0.2,1")), budget())
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import numpy as np

from pac_host.model.step_noise import StepNoise
from pac_host.model.table import BUILTIN, GaitTable

PATH = Path(__file__).resolve().with_name("best_known.json")


@cache
def _doc() -> dict:
    return json.loads(PATH.read_text())


def budget() -> int:
    """The gait cycles per run the records hold for."""
    return int(_doc()["budget"])


def entries() -> dict[str, dict]:
    """Each robot's record (turn cycle, fitness, and the placed record where there is one)."""
    return {name: rec for name, rec in _doc().items() if isinstance(rec, dict)}


def fitness(robot: str) -> int | None:
    """The best fitness known on ``robot``, or None when none is recorded."""
    return entries().get(robot, {}).get("fitness")


def fitnesses() -> dict[str, int]:
    """Every robot's best known fitness, by name."""
    return {name: rec["fitness"] for name, rec in entries().items()}


def builtin_table(name: str) -> GaitTable:
    """The built-in robot a record names: a built-in table or one of the robots."""
    from pac_host.model import robots

    return robots.build(name) if name in robots.ROBOTS else BUILTIN[name]()


def robot_of(table: GaitTable) -> str | None:
    """The name of the built-in robot ``table`` is (its rows and effects, whatever it is
    called: a file the robots were written to is the robot), or None."""
    effects = [e.to_json() for e in table.effects]
    for name in entries():
        built = builtin_table(name)
        if (np.allclose(built.rows, table.rows, rtol=0.0, atol=1e-9)
                and [e.to_json() for e in built.effects] == effects):
            return name
    return None


def robust(robot: str, noise: StepNoise) -> dict | None:
    """``robot``'s robust record at step ``noise`` (its entry whose ``step_noise`` is the
    noise's text form, e.g. "0.3,1"), or None."""
    text = noise.to_text()
    for rec in entries().get(robot, {}).get("robust", []):
        if rec["step_noise"] == text:
            return rec
    return None


def robust_for_table(table: GaitTable, run_budget: int) -> tuple[str, dict] | None:
    """The built-in robot ``table`` is and its robust record at the table's step noise, if it
    is one, has one at that noise and the records hold for ``run_budget``; else None."""
    found = for_table(table, run_budget)
    if found is None or table.step_noise.is_zero():
        return None
    rec = robust(found[0], table.step_noise)
    return None if rec is None else (found[0], rec)


def for_table(table: GaitTable, run_budget: int) -> tuple[str, dict] | None:
    """The built-in robot ``table`` is and its record, if it is one and the records hold for
    ``run_budget`` gait cycles a run; else None."""
    if run_budget != budget():
        return None
    name = robot_of(table)
    return (name, entries()[name]) if name is not None else None
