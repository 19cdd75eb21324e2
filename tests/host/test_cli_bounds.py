"""Every count a user gives is bounded: outside its range, one line naming the limit, exit 2,
before any work starts (so nothing is computed, printed or written)."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from pac_host import limits
from pac_host.cli.main import main
from pac_host.coverage import check_budget
from pac_host.errors import InputError
from pac_host.experiments.experiment import ExperimentConfig
from pac_host.robot.evolve import EvolveConfig


def one_line_exit_2(args: list[str], words: str) -> str:
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pac-host: error:"), res.output
    assert words in lines[0] and "Traceback" not in res.output
    return lines[0]


def test_simulate_budget_above_the_firmware_counter_is_one_line(tmp_path):
    line = one_line_exit_2(["simulate", "--budget", "100000000", "--turn-cycle", "1:2"],
                           "--budget must be 0..65535")
    assert "16 bits" in line and "100000000" in line


def test_simulate_budget_at_the_limit_runs():
    res = CliRunner().invoke(main, ["simulate", "--budget", "65535", "--turn-cycle", "12:1",
                                    "--json"])
    assert res.exit_code == 0, res.output


@pytest.mark.parametrize(("args", "words"), [
    (["experiment", "--generations", "1000000000"], "--generations must be 0..100000"),
    (["experiment", "--seeds", "0"], "--seeds must be 1..10000"),
    (["experiment", "--budget", "65536"], "--budget must be 1..65535"),
    (["experiment", "--optimum-runs", "-1"], "--optimum-runs must be 1..1000"),
    (["evolve", "--budget", "70000"], "--budget must be 1..65535"),
    (["evolve", "--cga-population", "2"], "--cga-population must be 4..100000"),
    (["evolve", "--model-generations", "99999999"], "--model-generations must be 0..10000"),
    (["evolve", "--interval", "0"], "--interval must be 1..100000"),
    (["measure", "--repeats", "1"], "--repeats must be 2..1000"),
    (["evolve", "--profile", "paper", "--search-while-walking"],
     "--search-while-walking needs an anytime profile"),
    (["simulate", "--budget", "lots", "--turn-cycle", "1:2"], "'lots' is not a valid integer"),
])
def test_out_of_range_counts_are_one_line(tmp_path, args, words):
    one_line_exit_2([*args, "--out", str(tmp_path / "o")] if args[0] != "simulate" else args,
                    words)
    assert not (tmp_path / "o").exists()  # refused before anything was written


@pytest.mark.parametrize("args", [
    ["simulate", "--turn-cycle", "1:2", "--placement-error", "0.5,1", "--seed", "-1"],
    ["optimize", "--evaluations", "100", "--seed", "-1"],
    ["experiment", "--seed", "-1"],
    ["evolve", "--seed", "-1"],
    ["evolve", "--sim-seed", "-1"],
    ["measure", "--seed", "-1"],
    ["diagnose", "--seed", "-1"],
    ["camera", "render", "--seed", "-1"],
])
def test_a_negative_seed_is_one_line(tmp_path, args):
    """numpy's generators take non-negative seeds: refused before any work, not a traceback."""
    one_line_exit_2([*args, "--out", str(tmp_path / "o")] if args[0] in ("experiment", "evolve")
                    else args, f"{args[-2]} must be 0..")
    assert not (tmp_path / "o").exists()


def test_help_shows_the_ranges():
    res = CliRunner().invoke(main, ["simulate", "--help"])
    assert "--budget 0..65535" in res.output


def test_library_configs_are_bounded_too():
    with pytest.raises(InputError, match="65535"):
        check_budget(limits.MAX_GAIT_CYCLES + 1)
    assert check_budget(limits.MAX_GAIT_CYCLES) == limits.MAX_GAIT_CYCLES
    with pytest.raises(InputError, match="--generations"):
        ExperimentConfig(generations=10**9).check()
    with pytest.raises(InputError, match="--budget"):
        EvolveConfig(budget=10**6).check()
    with pytest.raises(InputError, match="--seeds"):
        ExperimentConfig(seeds=True).check()  # a bool is not a count
