"""Step noise in the emulator's world (`pac-sim --step-noise`, `evolve --sim-step-noise`):
drawn per gait cycle from its own stream, so zero noise changes no pose and no other draw."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.cli.evolve import evolve_cmd
from pac_host.cli.link_options import SIM_NAMES, emulator_options
from pac_host.errors import InputError
from pac_host.model import integrate, parse_effect, rollout, shifted_table, step_moves
from pac_host.model.kinematics import moves_between
from pac_host.model.step_noise import NONE, StepNoise, parse_step_noise
from pac_sim.cli import build_config
from pac_sim.cli import main as pac_sim_main
from pac_sim.world import World

EFFECTS = tuple(parse_effect(e) for e in ("transition:alpha=0.3", "battery_sag:beta=0.002",
                                          "floor_slope:s=0.4,theta=30"))
GAITS = [12, 12, 3, 3, 3, 19, 25, 12] * 5
START = (50.0, 20.0, 80.0)


def _walk(world: World, gaits: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """True and observed poses after each gait cycle of one run."""
    prev = None
    for i, g in enumerate(gaits):
        world.advance(g, i, prev)
        prev = g
    true = np.array([s.true_pose for s in world.history])
    seen = np.array([s.observed for s in world.history])
    return true, seen


def test_a_noise_free_world_moves_as_the_model_and_its_tracker_draws_are_unchanged():
    table = shifted_table()
    quiet = World(table, EFFECTS, START, (0.5, 1.0), np.random.default_rng(4))
    true, seen = _walk(quiet, GAITS)
    pose, prev, want = np.array(START), None, []
    for i, g in enumerate(GAITS):  # the world's advance before step noise, gait cycle by cycle
        body, drift = step_moves(table.rows, np.array([g]), EFFECTS, n0=i, prev_gait=prev)
        pose = integrate(pose, body, drift)[-1]
        want.append(pose)
        prev = g
    np.testing.assert_array_equal(true, np.array(want))
    np.testing.assert_allclose(true, rollout(table.rows, START, GAITS, EFFECTS)[1:], atol=1e-9)
    zero = World(table.with_step_noise(NONE), EFFECTS, START, (0.5, 1.0),
                 np.random.default_rng(4))
    true0, seen0 = _walk(zero, GAITS)
    assert np.array_equal(true0, true) and np.array_equal(seen0, seen)
    # with step noise the path moves, but the tracker's noise on it is the same draws
    noisy = World(table.with_step_noise(parse_step_noise("0.3,1")), EFFECTS, START,
                  (0.5, 1.0), np.random.default_rng(4))
    true1, seen1 = _walk(noisy, GAITS)
    assert np.abs(true1 - true).max() > 0.5
    np.testing.assert_allclose(seen1 - true1, seen - true, atol=1e-9)


def test_the_worlds_step_errors_have_the_tables_deviations_per_gait_cycle():
    sd = np.tile([0.2, 0.2, 0.5], (32, 1))
    sd[3] = [0.6, 0.6, 3.0]  # a turn noisier than the straight
    world = World(shifted_table().with_step_noise(StepNoise(sd)), (), START, (0.0, 0.0),
                  np.random.default_rng(0))
    gaits = [12, 3] * 5000
    true, _ = _walk(world, gaits)
    poses = np.vstack([np.array(START)[None], true])
    err = moves_between(poses) - shifted_table().rows[gaits]
    for gid in (12, 3):
        e = err[np.array(gaits) == gid]
        np.testing.assert_allclose(e.mean(axis=0), 0.0, atol=0.06)
        np.testing.assert_allclose(e.std(axis=0), sd[gid], rtol=0.05)


def test_a_placed_runs_step_noise_repeats_from_its_noise_seed():
    table = shifted_table().with_step_noise(parse_step_noise("0.3,1"))
    paths = []
    for other in (1, 2):  # different streams before the run
        world = World(table, (), START, (0.5, 1.0), np.random.default_rng(other))
        _walk(world, [12, 3])
        world.place(START, noise_seed=9)
        world.history.clear()
        paths.append(_walk(world, GAITS))
    assert np.array_equal(paths[0][0], paths[1][0]) and np.array_equal(paths[0][1], paths[1][1])


def _sim_config(args: list[str]):
    ctx = pac_sim_main.make_context("pac-sim", args)
    with ctx:
        opts = {k: v for k, v in ctx.params.items() if k != "link_path"}
        return build_config(**opts)


def test_pac_sim_step_noise_sets_the_worlds_table(tmp_path):
    assert _sim_config(["--step-noise", "0.3,1"]).table.step_noise == parse_step_noise("0.3,1")
    assert _sim_config([]).table.step_noise.is_zero()
    with pytest.raises(InputError, match="--step-noise takes CM,DEG"):
        _sim_config(["--step-noise", "0.3"])


def _emulator(args: list[str]):
    ctx = evolve_cmd.make_context("evolve", ["--out", "unused", *args])
    with ctx:
        sim = {k: ctx.params[k] for k in SIM_NAMES}
        return emulator_options(sim, ctx.params["port"])


def test_evolve_sim_step_noise_sets_the_emulators_robot():
    assert _emulator(["--sim-step-noise", "0.5,2"]).table.step_noise == \
        parse_step_noise("0.5,2")
    assert _emulator([]).table.step_noise.is_zero()
    with pytest.raises(InputError, match="^--sim-step-noise takes CM,DEG"):
        _emulator(["--sim-step-noise", "1,2,3"])
    with pytest.raises(InputError, match="does not apply with --port"):
        _emulator(["--sim-step-noise", "0.5,2", "--port", "/dev/null"])
