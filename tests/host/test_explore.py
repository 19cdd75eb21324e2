"""Thompson-sampled tests (``PALConfig.explore``): a share of each anytime search's budget
searches one draw from the corrected model's posterior, from the search's best, and the best
found there takes the test after the best."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pac_host.coverage import parse_turn_cycle, simulate
from pac_host.errors import InputError
from pac_host.learning import pal, profiles
from pac_host.model import measured_table, robots


def _cfg(explore: float) -> pal.PALConfig:
    return replace(profiles.apply("default", pal.PALConfig()), explore=explore, shapes="none",
                   search_evaluations=20_000, generations=80, cga_population=32)


def run_recorded(cfg: pal.PALConfig, seed: int = 0):
    """A PAL run on the noisy_rows robot: its records and the state after each punctuation."""
    rng = np.random.default_rng(seed)
    robot = pal.SimulatedRobot(robots.build("noisy_rows"), cfg.budget)
    state = pal.initial_state(measured_table(), rng, cfg)
    records, states = [], []
    pal.run(state, robot, rng, cfg, lambda st, rec: (records.append(rec), states.append(st)))
    return records, states


def test_the_best_on_a_posterior_draw_takes_the_test_after_the_best():
    records, states = run_recorded(_cfg(0.25))
    assert len(records) == 3
    for rec, st in zip(records, states, strict=True):
        explored = parse_turn_cycle(rec["search"]["explore"])
        assert np.array_equal(np.array(st.search["explore"]), explored)
        # it was climbed from the search's best on the draw, so it does no worse there
        draw = st.models[1]
        on_draw = simulate(draw, np.stack([explored, st.cga_pop[0]]), 200, st.model_effects)
        assert on_draw.fitness[0] >= on_draw.fitness[1]
    # the next punctuation tests it second wherever it differs from the best
    differs = 0
    for rec, st in zip(records[1:], states[:-1], strict=True):
        explored = np.array(st.search["explore"])
        tests = [parse_turn_cycle(t) for t in rec["tests"]]
        if not np.array_equal(explored, tests[0]):
            differs += 1
            assert np.array_equal(tests[1], explored)
    assert differs >= 1
    assert json.loads(json.dumps(states[-1].search))["explore"] == states[-1].search["explore"]


def test_without_explore_no_draw_is_searched_and_the_runs_differ():
    plain, _ = run_recorded(_cfg(0.0))
    assert all("explore" not in r["search"] for r in plain)
    explored, states = run_recorded(_cfg(0.25))
    # a quarter less on the model (what the chain spent past its budgets it owes the next)
    spent = sum(r["search"]["evaluations"] for r in explored)
    assert spent == 15_000 * 3 + states[-1].search["overrun"]
    assert [r["search"]["explore_evaluations"] for r in explored] == [5_000] * 3
    assert [r["tests"] for r in plain] != [r["tests"] for r in explored]


def test_explore_is_checked():
    with pytest.raises(InputError, match="explore"):
        replace(_cfg(0.0), explore=1.0).check()
    with pytest.raises(InputError, match="explore"):
        replace(_cfg(0.0), explore=-0.1).check()
    with pytest.raises(InputError, match="anytime"):
        pal.PALConfig(explore=0.25).check()
    _cfg(0.5).check()


def test_evolve_and_experiment_take_explore_from_the_command_line(tmp_path):
    from click.testing import CliRunner

    from pac_host.cli.main import main
    from pac_host.robot.evolve import EvolveConfig, load_config

    assert EvolveConfig().explore == 0.0  # a run saved before it explored nothing
    out = tmp_path / "run"
    res = CliRunner().invoke(main, ["evolve", "--out", str(out), "--generations", "20",
                                    "--interval", "20", "--cga-population", "16",
                                    "--initial-generations", "5", "--search-evaluations",
                                    "2000", "--budget", "100", "--explore", "0.3"])
    assert res.exit_code == 0, res.output
    assert load_config(out).explore == 0.3 and load_config(out).pal().explore == 0.3
    logged = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert all("explore" in rec["search"] for rec in logged)
    for args, message in ((["--explore", "1"], "--explore"),
                          (["--explore", "0.2", "--profile", "paper"], "anytime")):
        bad = CliRunner().invoke(main, ["experiment", "--out", str(tmp_path / "bad"), *args])
        assert bad.exit_code == 2 and message in bad.output, bad.output
