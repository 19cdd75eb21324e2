"""Profiles: the paper profile gives, bit for bit, what the project gave before the anytime
search existed; the default profile searches with a budget of evaluations per punctuation."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.errors import InputError
from pac_host.learning import pal, profiles
from pac_host.model import measured_table, shifted_table

SHORT = ["experiment", "--seeds", "2", "--generations", "80", "--initial-generations", "60",
         "--optimum-runs", "1", "--optimum-generations", "60", "--budget", "150"]
# Computed by the code before profiles existed (the CGA between punctuations, the numpy
# simulator only), with the command SHORT: per run, the operational coverage at each
# punctuation, the final operational turn cycle and a digest of the final best model.
BEFORE = {
    ("full", 0): ([4, 4, 4], "4:1,23:24,0:3,26:48,20:22,23:35,12:39,26:18,11:22",
                  "b05a476743025973"),
    ("full", 1): ([2, 5, 5], "21:62,8:42,2:16,23:24,19:6,3:44,6:12,7:11,26:28",
                  "141fd8af44368d5a"),
    ("oracle", 0): ([5, 16, 16], "5:3,22:58,8:38,23:34,12:13,5:47,23:3,0:16,28:54",
                    "62cbd0a0a2db7c8f"),
    ("oracle", 1): ([8, 11, 11], "23:63,8:43,4:24,22:24,27:2,18:35,27:3,20:19,16:27",
                    "62cbd0a0a2db7c8f"),
    ("partial", 0): ([4, 4, 14], "5:2,23:36,9:46,11:11,7:23,26:42,28:63,4:58,0:3",
                     "b7ed3d7698711de5"),
    ("partial", 1): ([2, 2, 2], "21:38,10:41,6:17,23:25,15:21,23:57,25:18,7:6,5:46",
                     "fa1a39a2c031ca4f"),
}


def test_paper_profile_reproduces_the_results_from_before_bit_for_bit(tmp_path):
    res = CliRunner().invoke(main, [*SHORT, "--profile", "paper", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["optimum"] == 16
    got = {(r["method"], r["seed"]): (
        r["coverage"], r["operational"],
        hashlib.sha256(json.dumps(r["final_model"]).encode()).hexdigest()[:16])
        for r in summary["runs"]}
    assert got == BEFORE
    assert json.loads((tmp_path / "optimum.json").read_text())["search"]["method"] == "CGA"
    # the paper's question by default: full against partial (their runs differ), the oracle
    assert summary["config"]["methods"] == ["full", "partial", "oracle"]
    assert 0 <= summary["comparison"]["tests"]["reached_optimum_fisher_exact_p"] <= 1
    # no record at budget 150: robot time counts against the experiment's own optimum
    assert summary["best_known"]["used"] == "optimum" and summary["best_known"]["fitness"] == 16


def test_profiles_are_pal_overrides():
    assert profiles.apply("paper", pal.PALConfig()) == pal.PALConfig(**pal.PAPER)
    cfg = profiles.apply("default", pal.PALConfig())
    assert cfg.search == "ils" and cfg.search_evaluations > 0
    with pytest.raises(InputError):
        profiles.apply("fast", pal.PALConfig())


@pytest.mark.parametrize("setting", ["shorten_windows", "library_restarts", "finish_moves",
                                     "refine_effects"])
def test_a_search_setting_is_on_in_the_default_profile_and_off_in_runs_saved_before_it(
        setting):
    """Settings added to the default's search: the paper profile and a run saved before the
    setting existed load without it; an evolve run's config passes it to PAL."""
    from pac_host.robot.evolve import EvolveConfig

    assert getattr(profiles.apply("default", pal.PALConfig()), setting)
    assert not getattr(profiles.apply("paper", pal.PALConfig()), setting)
    assert not getattr(pal.PALConfig(), setting)
    assert not getattr(EvolveConfig(), setting)  # a run saved before it loads without it
    assert getattr(EvolveConfig(**{setting: True}).pal(), setting)


def test_anytime_search_in_a_worker_equals_the_search_in_line():
    """evolve runs its tests concurrently, experiment in line: without a search while walking
    (which has no budget) both spend the budget after the tests, and give the same run."""
    cfg = replace(profiles.apply("default", pal.PALConfig(cga_population=16,
                                                          model_population=8,
                                                          model_generations=3,
                                                          generations=40, interval=20)),
                  search_evaluations=3000)
    robot = pal.SimulatedRobot(shifted_table())
    out = []
    for concurrent in (False, True):
        rng = np.random.default_rng(5)
        state = pal.initial_state(measured_table(), rng, cfg)
        recs, owed = [], []
        for _ in range(2):
            state, rec = pal.punctuate(state, robot, rng, cfg, concurrent=concurrent)
            state, _ = pal.advance_cga(state, cfg.interval, rng, cfg)
            recs.append(rec)
            owed.append(state.search["overrun"])
        out.append((recs, owed, state.cga_pop.tolist(), state.models.tolist()))
    assert out[0] == out[1]
    search = out[0][0][0]["search"]
    # chain 0 ends the move it is in and owes the next budget what it spent past its own
    assert search["evaluations"] + search["explore_evaluations"] == 3000 + out[0][1][0]
    assert search["explore_evaluations"] == 750  # the default's quarter on a posterior draw


def test_anytime_search_spends_its_budget_on_the_model_the_tests_corrected():
    """The tests are chosen on the initial (measured) model; the shifted robot's tests correct
    it, and the search then improves the turn cycle on the corrected model, not the old one."""
    cfg = replace(profiles.apply("default", pal.PALConfig(cga_population=16, model_population=8,
                                                          model_generations=2)),
                  search_evaluations=20000)
    rng = np.random.default_rng(2)
    state = pal.initial_state(measured_table(), rng, cfg)
    pop = state.cga_pop
    new, rec = pal.punctuate(state, pal.SimulatedRobot(shifted_table()), rng, cfg)
    assert not np.array_equal(new.models[0], state.models[0])  # the tests corrected the model
    before = pal.cga.fitness(new.models[0], pop, cfg.budget, new.model_effects).max()
    after = pal.cga.fitness(new.models[0], new.cga_pop[:1], cfg.budget, new.model_effects)[0]
    assert rec["search"]["best_score"] == after
    assert after > before
    stale = pal.cga.fitness(state.models[0], new.cga_pop[:1], cfg.budget)[0]
    assert stale != after  # scored on the old model the search's best is another figure


def test_search_while_walking_searches_until_the_robot_has_walked_the_tests():
    """evolve on a real robot: once its budget is spent the worker searches on until the
    tests end (the robot's walking time becomes search time); in line it does not."""
    import time

    class SlowRobot(pal.SimulatedRobot):
        def run_tests(self, tests):
            time.sleep(1.0)  # the robot walking
            return super().run_tests(tests)

    base = replace(profiles.apply("default", pal.PALConfig(cga_population=16, model_population=8,
                                                           model_generations=2)),
                   search_evaluations=2000, finish_moves=False)  # spent exactly: cut at it
    robot = SlowRobot(shifted_table())
    for walking, concurrent in ((True, True), (False, True), (True, False)):
        cfg = replace(base, search_while_walking=walking)
        rng = np.random.default_rng(3)
        state = pal.initial_state(measured_table(), rng, cfg)
        state, rec = pal.punctuate(state, robot, rng, cfg, concurrent=concurrent)
        extra = rec["search"].get("evaluations_while_walking", 0)
        assert rec["search"]["evaluations"] + rec["search"]["explore_evaluations"] == 2000
        assert (extra > 2000) == (walking and concurrent), (walking, concurrent, extra)
        assert state.search is not None
