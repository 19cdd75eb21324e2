"""Residuals use the world's own effect code: with the true effects and no noise they vanish."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.diagnose.residuals import batch_of, end_errors, step_residuals, where_report
from pac_host.model import Effect, integrate, measured_table
from pac_host.model.kinematics import moves_between

TRUE = [Effect("transition", {"alpha": 0.4}), Effect("battery_sag", {"beta": 0.0005}),
        Effect("floor_slope", {"s": 0.7, "theta": 30.0}), Effect("yaw_bias", {"delta": 0.8})]


def test_moves_between_inverts_integrate():
    rng = np.random.default_rng(1)
    body = rng.normal(size=(3, 20, 3)) * [8, 3, 20]
    start = rng.normal(size=(3, 3)) * 50
    np.testing.assert_allclose(moves_between(integrate(start, body)), body, atol=1e-9)


def test_noise_free_residuals_vanish_with_true_effects(make_runs):
    runs = make_runs(TRUE, n_runs=8, n_cycles=30, pos=0.0, head=0.0)
    b = batch_of(runs)
    rows = measured_table().rows
    res = step_residuals(rows, b, TRUE)
    assert np.abs(res).max() < 1e-9
    assert end_errors(rows, b, TRUE).max() < 1e-8
    # without the effects the same data show a gap
    assert np.abs(step_residuals(rows, b, [])).max() > 0.5
    assert end_errors(rows, b, []).mean() > 5


def test_where_finds_the_yaw_bias(make_runs):
    runs = make_runs([Effect("yaw_bias", {"delta": 1.0})], n_runs=10, n_cycles=40)
    b = batch_of(runs)
    w = where_report(b, step_residuals(measured_table().rows, b, []))
    for row in w["by_gait_cycle"]:
        if row["n"] >= 30:  # every well-sampled gait cycle turns 1 degree more
            assert row["mean"][2] == pytest.approx(1.0, abs=0.5)
    assert w["by_component"]["dH"] > w["by_component"]["F"]
    ctx = w["by_context"]
    assert set(ctx) == {"change", "power_on", "heading", "turn"}
    assert ctx["change"]["repeat"]["n"] + ctx["change"]["after_change"]["n"] == \
        b.n_steps - len(runs)


def test_blind_case_world_is_the_emulators_world(cycles):
    """The benchmark's runs move exactly as the emulator's world moves, step by step."""
    from pac_host.diagnose.synth import world_runs
    from pac_host.model import GaitTable
    from pac_sim.world import World

    rows = measured_table().rows
    runs = world_runs(rows, TRUE, cycles[:3], 25, np.random.default_rng(0), 0.0, 0.0,
                      runs_per_session=3)
    for run in runs:
        world = World(GaitTable(rows), TRUE, start=run.start_pose)
        prev = None
        for i, g in enumerate(run.gait_cycles):
            sample = world.advance(int(g), run.cycles_since_power_on + i, prev)
            prev = int(g)
            np.testing.assert_allclose(sample.true_pose, run.poses[i], atol=1e-9)
