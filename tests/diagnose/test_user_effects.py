"""User-defined effects (``--effects-module``): one loader for every command, and a stall
model end to end: pac-sim's world stalls, the robot's runs are recorded, the diagnosis finds
the stall among the library's effects and says what its random nature leaves."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.errors import InputError
from pac_host.model import Effect, measured_table, step_moves
from pac_host.model.effects import EFFECT_SPECS, ParamSpec, register_effect
from pac_host.model.effects_module import forget_user_effects, load_effects_module
from pac_sim.cli import main as pac_sim_main

BIN = Path(sys.executable).parent
STALL = Path(__file__).resolve().parents[2] / "examples" / "effects" / "stall_effect.py"


@pytest.fixture
def clean_registry():
    yield
    forget_user_effects()


def _invoke(*args: str, command=main):
    return CliRunner().invoke(command, list(args))


def test_stall_module_moves_the_model_by_its_expectation_and_the_world_at_random(
        clean_registry):
    assert load_effects_module(STALL) == ["stall"]
    assert load_effects_module(STALL) == ["stall"]  # loading twice is harmless
    rows, ids = measured_table().rows, np.full(400, 12)
    model, _ = step_moves(rows, ids, [Effect("stall", {"p": 0.3})])
    assert np.allclose(model, 0.7 * rows[12])
    world, _ = step_moves(rows, ids, [Effect("stall", {"p": 0.3})],
                          rng=np.random.default_rng(1))
    stalled = (world == 0).all(axis=1)
    assert 0.2 < stalled.mean() < 0.4 and np.allclose(world[~stalled], rows[12])


def test_register_effect_refuses_what_the_registry_cannot_hold(clean_registry):
    ident = lambda body, ctx, **p: body  # noqa: E731
    with pytest.raises(InputError, match="built-in"):
        register_effect("yaw_bias", [ParamSpec("d", 0, 1)], ident)
    with pytest.raises(InputError, match="continuous"):
        register_effect("steps", [ParamSpec("k", 0, 3, integer=True)], ident)
    register_effect("bad_shape", [ParamSpec("d", 0, 1)], lambda body, ctx, d: body[..., :2])
    with pytest.raises(InputError, match="apply returned shape"):
        step_moves(measured_table().rows, np.array([12]), [Effect("bad_shape", {"d": 0.5})])
    assert "bad_shape" in EFFECT_SPECS


def test_bad_effects_modules_are_one_line_and_exit_2(tmp_path, clean_registry):
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('oops')\n")
    empty = tmp_path / "empty.py"
    empty.write_text("X = 1\n")
    cases = [(tmp_path / "missing.py", "no such file", ["simulate", "--turn-cycle", "12:1"], main),
             (broken, "RuntimeError: oops", [], pac_sim_main),
             (empty, "defines no effect", ["diagnose", "--model", "measured", "--runs", "x"],
              main)]
    for path, words, cmd, command in cases:
        res = _invoke(*cmd, "--effects-module", str(path), command=command)
        lines = res.output.strip().splitlines()
        assert res.exit_code == 2 and len(lines) == 1, (cmd, res.output)
        assert words in lines[0] and "error:" in lines[0]


def test_stall_end_to_end_through_simulate_pac_sim_and_diagnose(tmp_path, clean_registry):
    mod = ["--effects-module", str(STALL)]
    plain = _invoke("simulate", "--turn-cycle", "12:10", "--budget", "20")
    stalled = _invoke("simulate", *mod, "--effect", "stall:p=0.5", "--turn-cycle", "12:10",
                      "--budget", "20")
    assert plain.exit_code == 0 and stalled.exit_code == 0, stalled.output
    x_end = [float(r.output.splitlines()[21].split()[1]) for r in (plain, stalled)]
    assert x_end[1] - 45 == pytest.approx(0.5 * (x_end[0] - 45), rel=1e-3)  # the expectation

    sim = subprocess.Popen([str(BIN / "pac-sim"), "--realtime", "0", "--tracker-noise", "0.5,1",
                            "--seed", "3", *mod, "--effect", "stall:p=0.25"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = sim.stdout.readline().split()[-1]
        tracker = sim.stdout.readline().split()[-1]
        res = _invoke("measure", "--port", port, "--observer", f"tracker:{tracker}",
                      "--placer", "tracker", "--ids", "12,28,3,20", "--repeats", "4",
                      "--cycles", "25", "--table", "shifted", "--out", str(tmp_path / "m.json"))
        assert res.exit_code == 0, res.output
    finally:
        sim.send_signal(signal.SIGTERM)
        sim.wait(timeout=10)
    runs = tmp_path / "m.runs.jsonl"
    rep = tmp_path / "report.json"
    res = _invoke("diagnose", *mod, "--model", "shifted", "--runs", str(runs), "--seed", "1",
                  "--json", str(rep))
    assert res.exit_code == 0, res.output
    doc = json.loads(rep.read_text())
    assert doc["selected"][0] == "stall"
    assert doc["selected_effects"][0]["params"]["p"] == pytest.approx(0.25, abs=0.06)
    assert doc["unexplained"]["kind"] == "intermittent"  # the model predicts the expectation
    forget_user_effects()
    res = _invoke("diagnose", "--model", "shifted", "--runs", str(runs), "--seed", "1")
    assert "stall" not in res.output and "partly_unexplained" in res.output  # no module


def test_every_command_that_takes_an_effect_takes_the_module():
    from pac_sim.cli import main as sim

    def params(cmd):
        return {p.name for p in cmd.params} | {o for p in cmd.params for o in p.opts}

    for path in (["simulate"], ["experiment"], ["evolve"], ["measure"], ["diagnose"],
                 ["table", "show"], ["table", "export"]):
        cmd = main
        for name in path:  # through get_command: the top-level group loads commands lazily
            cmd = cmd.get_command(click.Context(cmd), name)
        assert "--effects-module" in params(cmd), path
    assert "--effects-module" in params(sim)
