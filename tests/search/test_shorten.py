"""Shorter loops of a stalled chain's sweep (``shorten_after``): two genes re-set so the loop is
1-3 gait cycles shorter and its pass ends where it did; a chain that has stalled for a few
kicks tries them; the setting reaches the chains from ``optimize``, PAL and the command line,
and bad values are one clear error."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from pac_host.coverage import parse_turn_cycle, simulate
from pac_host.errors import InputError
from pac_host.learning import pal, profiles
from pac_host.model import measured_table, robots, shifted_table
from pac_host.model.kinematics import loop_moves
from pac_host.search import local
from pac_host.search.kicks import WEIGHT, loop_table
from pac_host.search.local import Objective, climb, shorten
from pac_host.search.neighbours import _VALUES, canonical, slots
from pac_host.search.optimize import OptimizeConfig, optimize
from pac_host.search.shorten import (
    SHORTEN_AFTER,
    SHORTER_BY,
    check_shorten_after,
    shorter_loops,
)
from tests.search.test_kick_length import check_anytime_option

LOOP = parse_turn_cycle("10:1,25:8,21:11,17:2,9:4,5:8,22:3,11:1,1:6")  # 44 cycles on shifted
# A local optimum the default's chains stall on, on the exact noisy_rows table: 49, a 37-cycle
# loop (the best known there walks the same three-row pass in 35 cycles and scores 52)
STALLED = "12:4,24:7,22:10,9:2,1:1,7:2,6:5,13:3,0:3"


def _error(y: np.ndarray, x: np.ndarray, repeated: np.ndarray) -> np.ndarray:
    a, b = loop_moves(y, repeated), loop_moves(x, repeated)
    return np.abs(a[..., 0] - b[0]) + WEIGHT * np.abs(a[..., 1] - b[1])


def test_every_proposal_is_a_shorter_loop_with_two_genes_reset():
    repeated = loop_table(shifted_table().rows)
    y = shorter_loops(LOOP, repeated, 200)
    n_slots = len(slots(canonical(LOOP, 200), 200))
    assert len(y) == 64 * n_slots * (n_slots - 1) // 2  # TOP for every pair of slots
    lengths = y[:, :, 1].sum(axis=1)
    assert (lengths < 44).all() and (lengths >= 44 - SHORTER_BY).all()
    assert ((y != canonical(LOOP, 200)).any(axis=2).sum(axis=1) <= 2).all()
    # they close the pass far better than shorter loops drawn at random
    rng = np.random.default_rng(0)
    drawn = np.repeat(LOOP[None], 2000, axis=0)
    for k in range(len(drawn)):
        j = rng.choice(9, size=2, replace=False)
        drawn[k, j] = _VALUES[rng.integers(len(_VALUES) - 1, size=2)]
    drawn = drawn[(drawn[:, :, 1].sum(axis=1) < 44)]
    assert np.median(_error(y, LOOP, repeated)) < np.median(_error(drawn, LOOP, repeated)) / 5


def test_the_first_proposal_of_a_pair_is_the_closest_there_is():
    """Checked against every re-setting of the first two genes, the net moves computed by
    :func:`loop_moves` (not the prefix-and-suffix composition the proposals use)."""
    repeated = loop_table(shifted_table().rows)
    x = canonical(LOOP, 200)
    first = shorter_loops(x, repeated, 200)[0]
    assert (first[2:] == x[2:]).all()  # the first pair is genes 0 and 1
    now = int(x[0, 1] + x[1, 1])
    pairs = [(a, b) for a, b in itertools.product(range(len(_VALUES)), repeat=2)
             if now - SHORTER_BY <= _VALUES[a, 1] + _VALUES[b, 1] < now]
    every = np.repeat(x[None], len(pairs), axis=0)
    every[:, 0] = _VALUES[[a for a, _ in pairs]]
    every[:, 1] = _VALUES[[b for _, b in pairs]]
    best = float(_error(every, x, repeated).min())
    assert _error(first, x, repeated) == pytest.approx(best, abs=1e-9)


def test_a_loop_the_budget_does_not_repeat_has_none():
    repeated = loop_table(shifted_table().rows)
    assert len(shorter_loops(parse_turn_cycle("12:60,3:60,5:60,7:30"), repeated, 200)) == 0
    assert len(shorter_loops(LOOP, repeated, 40)) == 0  # 44 cycles: cut in its first pass


def test_shortening_lifts_a_stalled_sweep_on_noisy_rows():
    rows = robots.build("noisy_rows").rows
    objective = Objective(rows)
    x = parse_turn_cycle(STALLED)
    rng = np.random.default_rng(0)
    x, score = climb(x, int(objective(x[None])[0]), objective, rng)
    assert objective.fitness(score) == 49  # a local optimum of the climb
    found = shorten(x, score, objective, rng)
    assert found is not None
    y, s = found
    assert s > score and int(simulate(rows, y, 200).fitness[0]) >= 50
    assert int(y[:, 1].sum()) < int(x[:, 1].sum())  # by walking the pass in fewer cycles


def test_a_chain_tries_shorter_loops_after_so_many_stale_kicks(monkeypatch):
    seen: list[int] = []

    def recording(x, score, objective, rng, sample, windows):
        seen.append(chain.stale)
        return None

    monkeypatch.setattr(local, "shorten", recording)
    for after, expect in ((0, False), (3, True)):
        seen.clear()
        chain = local.Chain()
        chain.run(Objective(shifted_table().rows, limit=80_000), np.random.default_rng(0),
                  patience=10, shorten_after=after)
        assert bool(seen) == expect
        assert set(seen) <= {after}


def test_optimize_passes_the_setting_to_its_chains():
    rows = robots.build("noisy_rows").rows
    runs = [optimize(rows, OptimizeConfig(evaluations=150_000, seed=1, shapes="none",
                                          shorten_after=k)) for k in (0, 1)]
    assert runs[0]["chains"][0]["trace"] != runs[1]["chains"][0]["trace"]
    assert OptimizeConfig(evaluations=1).shorten_after == SHORTEN_AFTER  # optimize's default
    assert runs[1]["settings"]["shorten_after"] == 1


def test_pal_chains_shorten_with_the_profile_setting(monkeypatch):
    calls: list[int] = []
    real = local.shorten

    def recording(*args, **kw):
        calls.append(1)
        return real(*args, **kw)

    monkeypatch.setattr(local, "shorten", recording)
    cfg = replace(profiles.apply("default", pal.PALConfig()), shapes="none", explore=0.0,
                  search_chains=1, search_evaluations=60_000, generations=40,
                  cga_population=32, shorten_after=1)
    rng = np.random.default_rng(0)
    robot = pal.SimulatedRobot(robots.build("noisy_rows"), cfg.budget)
    state = pal.initial_state(measured_table(), rng, cfg)
    pal.run(state, robot, rng, cfg, lambda st, rec: None)
    assert calls
    calls.clear()
    pal.run(pal.initial_state(measured_table(), np.random.default_rng(0), cfg), robot,
            np.random.default_rng(0), replace(cfg, shorten_after=0), lambda st, rec: None)
    assert not calls


@pytest.mark.parametrize("bad", [-1, 10_001, 2.5, True])
def test_a_bad_setting_is_one_clear_error(bad):
    with pytest.raises(InputError, match="--shorten-after"):
        check_shorten_after(bad)
    with pytest.raises(InputError, match="--shorten-after"):
        OptimizeConfig(evaluations=10, shorten_after=bad).check()
    with pytest.raises(InputError, match="--shorten-after"):
        replace(profiles.apply("default", pal.PALConfig()), shorten_after=bad).check()


def test_the_command_line_takes_the_setting(tmp_path):
    from pac_host.robot.evolve import EvolveConfig

    assert EvolveConfig().shorten_after == 0  # a run saved before it: never
    assert profiles.apply("paper", pal.PALConfig()).shorten_after == 0
    with pytest.raises(InputError, match="anytime"):
        pal.PALConfig(shorten_after=5).check()  # the paper's CGA makes no kicks
    check_anytime_option(tmp_path, "--shorten-after", "shorten_after", SHORTEN_AFTER, "0", 0,
                         "5")
