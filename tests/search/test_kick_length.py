"""Closing kicks that prefer shorter loops (``kick_length_cost``): each gait cycle of the
kicked loop weighs as some cm of the repair's error, so among repairs about as close the one
leaving the loop shorter is taken; the setting reaches the kicks from ``optimize``, PAL and
the command line, and bad values are one clear error."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import parse_turn_cycle
from pac_host.errors import InputError
from pac_host.learning import pal, profiles
from pac_host.model import measured_table, robots, shifted_table
from pac_host.search.kicks import SHORTER, closing_kick, closure_error, kick, loop_table
from pac_host.search.optimize import OptimizeConfig, optimize

LOOP = parse_turn_cycle("10:1,25:8,21:11,17:2,9:4,5:8,22:3,11:1,1:6")  # 44 cycles on shifted


def _kicked(length_cost: float, n: int = 200) -> tuple[float, float]:
    """Mean loop length and mean closure error of ``n`` closing kicks of LOOP."""
    repeated = loop_table(shifted_table().rows)
    ys = [closing_kick(LOOP, np.random.default_rng(s), 2, 200, repeated,
                       length_cost=length_cost) for s in range(n)]
    return (float(np.mean([y[:, 1].sum() for y in ys])),
            float(np.mean([closure_error(y, LOOP, repeated) for y in ys])))


def test_a_length_cost_leaves_shorter_loops_that_still_close():
    plain_len, plain_err = _kicked(0.0)
    short_len, short_err = _kicked(SHORTER)
    assert short_len < plain_len - 10  # measured: 47 against 67 gait cycles
    repeated = loop_table(shifted_table().rows)
    random_err = np.mean([closure_error(kick(LOOP, np.random.default_rng(s), 2, 200), LOOP,
                                        repeated) for s in range(200)])
    assert plain_err < short_err < random_err / 2  # it trades a little closeness, not the repair


def test_optimize_passes_the_length_cost_to_its_kicks():
    rows = shifted_table().rows
    runs = [optimize(rows, OptimizeConfig(evaluations=60_000, seed=1, shapes="none",
                                          kick_length_cost=c)) for c in (0.0, SHORTER)]
    assert runs[0]["chains"][0]["trace"] != runs[1]["chains"][0]["trace"]
    assert runs[1]["settings"]["kick_length_cost"] == SHORTER
    again = optimize(rows, OptimizeConfig(evaluations=60_000, seed=1, shapes="none",
                                          kick_length_cost=SHORTER))
    assert again["genes"] == runs[1]["genes"]  # still reproducible from the seed


def test_pal_kicks_with_its_length_cost(monkeypatch):
    from pac_host.search import local

    costs: list[float] = []

    def recording(*args, length_cost=0.0, **kw):
        costs.append(length_cost)
        return closing_kick(*args, length_cost=length_cost, **kw)

    monkeypatch.setattr(local, "closing_kick", recording)
    cfg = replace(profiles.apply("default", pal.PALConfig()), shapes="none", explore=0.25,
                  search_chains=2, search_evaluations=60_000, generations=40,
                  cga_population=32, kick_length_cost=SHORTER)
    rng = np.random.default_rng(0)
    robot = pal.SimulatedRobot(robots.build("noisy_rows"), cfg.budget)
    state = pal.initial_state(measured_table(), rng, cfg)
    pal.run(state, robot, rng, cfg, lambda st, rec: None)
    assert costs and set(costs) == {SHORTER}  # every chain's kicks, the explored draw's too


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_a_bad_length_cost_is_one_clear_error(bad):
    with pytest.raises(InputError, match="--kick-length-cost"):
        OptimizeConfig(evaluations=10, kick_length_cost=bad).check()
    with pytest.raises(InputError, match="--kick-length-cost"):
        replace(profiles.apply("default", pal.PALConfig()), kick_length_cost=bad).check()
    with pytest.raises(InputError, match="anytime"):
        pal.PALConfig(kick_length_cost=1.0).check()  # the paper's CGA makes no kicks


def check_anytime_option(tmp_path, option: str, field: str, profile_value, override: str,
                         override_value, paper_value: str) -> None:
    """An anytime search setting on the command line: evolve saves the default profile's value,
    ``option override`` replaces it; ``option -1`` is exit 2 and one line naming the option in
    optimize and experiment; with ``--profile paper`` the option is refused (exit 2)."""
    from pac_host.robot.evolve import load_config

    small = ["--generations", "20", "--interval", "20", "--cga-population", "16",
             "--initial-generations", "5", "--search-evaluations", "2000", "--budget", "100"]
    for given, expected in (([], profile_value), ([option, override], override_value)):
        out = tmp_path / f"run{len(given)}"
        res = CliRunner().invoke(main, ["evolve", "--out", str(out), *small, *given])
        assert res.exit_code == 0, res.output
        assert getattr(load_config(out).pal(), field) == expected
        assert json.loads((out / "config.json").read_text())[field] == expected
    for cmd in (["optimize", "--evaluations", "100"],
                ["experiment", "--out", str(tmp_path / "bad")]):
        bad = CliRunner().invoke(main, [*cmd, option, "-1"])
        assert bad.exit_code == 2 and option in bad.output, bad.output
        assert "Traceback" not in bad.output
    paper = CliRunner().invoke(main, ["experiment", "--out", str(tmp_path / "p"), "--profile",
                                      "paper", option, paper_value])
    assert paper.exit_code == 2 and "anytime" in paper.output, paper.output


def test_the_command_line_takes_the_length_cost(tmp_path):
    from pac_host.robot.evolve import EvolveConfig

    assert EvolveConfig().kick_length_cost == 0.0  # a run saved before it: closeness alone
    assert profiles.apply("paper", pal.PALConfig()).kick_length_cost == 0.0  # the CGA kicks not
    # the default profile prefers shorter loops; the option overrides it
    check_anytime_option(tmp_path, "--kick-length-cost", "kick_length_cost", SHORTER, "0", 0.0,
                         "1")
