"""Shorter windows of a stalled sweep: four consecutive genes re-set so the loop is 1-3 gait
cycles shorter and the window's net move stays within a tolerance; met in the middle, checked
against every re-setting; tried after the two-gene proposals fail, once per loop and model; on
noisy_rows they lift the 36-cycle 50s that two genes cannot to the 35-cycle 53."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host import robots
from pac_host.coverage import parse_turn_cycle, simulate
from pac_host.model import shifted_table
from pac_host.model.kinematics import compose_moves, loop_moves
from pac_host.search import anytime, local
from pac_host.search.kicks import WEIGHT, loop_table
from pac_host.search.local import Objective, climb, shorten
from pac_host.search.neighbours import _VALUES, canonical
from pac_host.search.shorten import (
    SHORTER_BY,
    TOLERANCE,
    WINDOW,
    shorter_window,
    shorter_windows,
)

LOOP = parse_turn_cycle("10:1,25:8,21:11,17:2,9:4,5:8,22:3,11:1,1:6")  # 44 cycles on shifted
# 36-cycle loops the default's chains stalled on at 50 on the exact noisy_rows table, and the
# best known there (53, 35 cycles): no two genes re-set make either shorter and still 50
FIFTY = ("12:4,24:6,22:10,11:1,6:2,7:3,6:4,29:3,0:3",
         "30:3,24:7,22:10,14:1,6:3,6:5,7:1,12:3,0:3")
BEST = "12:4,24:6,22:10,6:1,31:1,0:1,7:6,30:3,0:3"


def _window_error(y: np.ndarray, x: np.ndarray, start: int, repeated: np.ndarray) -> np.ndarray:
    a = loop_moves(y[..., start:start + WINDOW, :], repeated)
    b = loop_moves(x[start:start + WINDOW], repeated)
    return np.abs(a[..., 0] - b[0]) + WEIGHT * np.abs(a[..., 1] - b[1])


def test_every_proposal_is_a_shorter_loop_with_one_window_reset_and_closed():
    repeated = loop_table(shifted_table().rows)
    x = canonical(LOOP, 200)
    y = shorter_windows(x, repeated, 200)
    assert len(y) > 100
    lengths = y[:, :, 1].sum(axis=1)
    assert (lengths < 44).all() and (lengths >= 44 - SHORTER_BY).all()
    changed = (y != x).any(axis=2)
    for k in range(len(y)):
        genes = np.flatnonzero(changed[k])
        starts = [s for s in range(len(x) - WINDOW + 1)
                  if genes.min() >= s and genes.max() < s + WINDOW]
        assert starts, f"proposal {k} changes genes {genes} in no window"
        assert min(float(_window_error(y[k], x, s, repeated)) for s in starts) <= TOLERANCE


def test_a_window_holds_every_resetting_there_is_closest_first():
    """Checked against all re-settings of a 4-cycle window (every front pair with every back
    pair, each composed whole), with a tolerance wide enough that some close."""
    repeated = loop_table(shifted_table().rows)
    x = canonical(parse_turn_cycle("12:2,13:1,14:1,0:0,9:4,5:8,22:3,11:1,1:6"), 200)
    tolerance = 30.0
    got = shorter_window(x, 0, repeated, tolerance=tolerance)
    values = repeated[_VALUES[:, 0], _VALUES[:, 1]]
    short = np.flatnonzero(_VALUES[:, 1] <= 3)  # the empty gene has 0 repetitions
    va, vb = (a.ravel() for a in np.meshgrid(short, short, indexing="ij"))
    keep = _VALUES[va, 1] + _VALUES[vb, 1] <= 3
    va, vb = va[keep], vb[keep]
    moves = compose_moves(values[va], values[vb])
    lengths = _VALUES[va, 1] + _VALUES[vb, 1]
    f, b = (a.ravel() for a in np.meshgrid(np.arange(len(va)), np.arange(len(va)),
                                           indexing="ij"))
    total = lengths[f] + lengths[b]
    f, b = f[(total >= 4 - SHORTER_BY) & (total < 4)], b[(total >= 4 - SHORTER_BY) & (total < 4)]
    target = loop_moves(x[:WINDOW], repeated)
    whole = compose_moves(moves[f], moves[b])
    err = np.abs(whole[:, 0] - target[0]) + WEIGHT * np.abs(whole[:, 1] - target[1])
    f, b = f[err <= tolerance], b[err <= tolerance]
    every = np.repeat(x[None], len(f), axis=0)
    for k, v in enumerate((va[f], vb[f], va[b], vb[b])):
        every[:, k] = _VALUES[v]
    assert len(every) > 10
    assert len(got) == len(every)
    assert {g.tobytes() for g in got} == {e.tobytes() for e in every}
    errors = _window_error(got, x, 0, repeated)
    assert (np.diff(errors) >= -1e-9).all()  # closest first


def test_a_loop_the_budget_does_not_repeat_has_none():
    repeated = loop_table(shifted_table().rows)
    assert len(shorter_windows(parse_turn_cycle("12:60,3:60,5:60,7:30"), repeated, 200)) == 0
    assert len(shorter_windows(LOOP, repeated, 40)) == 0


@pytest.mark.parametrize("fifty", FIFTY)
def test_windows_lift_a_fifty_that_two_genes_cannot(fifty):
    rows = robots.build("noisy_rows").rows
    objective = Objective(rows)
    x = parse_turn_cycle(fifty)
    x, score = climb(x, int(objective(x[None])[0]), objective, np.random.default_rng(0))
    assert objective.fitness(score) == 50  # a local optimum of the climb
    assert shorten(x, score, objective, np.random.default_rng(0), windows=False) is None
    found = shorten(x, score, objective, np.random.default_rng(0), windows=True)
    assert found is not None
    y, s = found
    assert int(simulate(rows, y, 200).fitness[0]) >= 51
    assert int(y[:, 1].sum()) < int(x[:, 1].sum())


def test_a_loops_windows_are_listed_once_per_objective(monkeypatch):
    calls: list[bytes] = []

    def counting(x, repeated, budget):
        calls.append(canonical(x, budget).tobytes())
        return np.empty((0,) + x.shape, dtype=np.int64)  # none lifts it

    monkeypatch.setattr(local, "shorter_windows", counting)
    rows = robots.build("noisy_rows").rows
    x = parse_turn_cycle(BEST)
    objective = Objective(rows)
    score = int(objective(x[None])[0])
    for _ in range(2):
        assert shorten(x, score, objective, np.random.default_rng(0)) is None
    assert len(calls) == 1
    assert shorten(x, score, Objective(rows), np.random.default_rng(0)) is None  # a new model
    assert len(calls) == 2
    assert shorten(x, score, Objective(rows), np.random.default_rng(0), windows=False) is None
    assert len(calls) == 2


def test_the_setting_reaches_the_chains_of_anytime_pal(monkeypatch):
    seen: list[bool] = []

    def recording(x, score, objective, rng, sample, windows):
        seen.append(windows)
        return None

    monkeypatch.setattr(local, "shorten", recording)
    rows = shifted_table().rows
    pop = np.repeat(LOOP[None], 4, axis=0)
    for windows in (False, True):
        seen.clear()
        anytime.advance(rows, pop, 60_000, np.random.default_rng(0), shorten_after=1,
                        windows=windows)
        assert seen and set(seen) == {windows}
