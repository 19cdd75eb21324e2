"""Effect-free data is not flagged: the whitening is exact along whole runs, the start pose is
treated as the data have it, and the step noise survives a noisy tracker.

Before, the whitening cut runs into chunks of 64 steps and dropped the pose shared across each
border (the whitened residuals of steps 63 and 64 correlated at -0.69), and effect-free runs of
40 to 79 gait cycles from an exact start were flagged ``partly_unexplained`` 6 times in 6.
``bench/bench_diagnose.py --clean`` checks 50 such designs.
"""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.diagnose import diagnose
from pac_host.diagnose.likelihood import whitener
from pac_host.diagnose.noise import NoiseFloor, estimate_noise
from pac_host.diagnose.residuals import batch_of, step_residuals
from pac_host.diagnose.synth import blind_case, world_runs
from pac_host.model import GaitTable, measured_table


@pytest.mark.parametrize("exact", [True, False])
def test_whitened_residuals_are_white_across_any_step(cycles, exact):
    # 120 runs of 70 steps, the true model and noise: steps 63 and 64 (a chunk border before,
    # correlated at -0.75) are as uncorrelated as any other pair (sd about 0.055 here), whether
    # the start pose is given or observed
    rng = np.random.default_rng(3)
    tc = np.concatenate([cycles] * 3)
    runs = world_runs(measured_table().rows, [], tc, 70, rng, 0.5, 1.0, start_exact=exact)
    b = batch_of(runs)
    nf = NoiseFloor(0.5, 1.0, "true", 0, True, start_cm=0.0 if exact else None,
                    start_deg=0.0 if exact else None)
    w = whitener(b, nf).whiten(step_residuals(measured_table().rows, b, [])).reshape(
        len(runs), 70, 3)
    assert np.var(w) == pytest.approx(1.0, abs=0.05)
    for i in (0, 1, 62, 63):
        corr = np.mean(w[:, i] * w[:, i + 1])
        assert abs(corr) < 0.2, (i, corr)


@pytest.mark.parametrize("exact", [True, False])
def test_the_start_pose_is_taken_as_the_data_have_it(cycles, exact):
    rng = np.random.default_rng(8)
    runs = world_runs(measured_table().rows, [], cycles[:24], 60, rng, 0.5, 1.0,
                      start_exact=exact)
    nf = estimate_noise(batch_of(runs))
    start = np.sqrt(nf.start_var())
    if exact:
        assert start[0] < 0.3 and start[2] < 0.6
    else:
        assert start[0] > 0.3 and start[2] > 0.6


@pytest.mark.parametrize("seed", [1, 2])
def test_step_noise_is_kept_under_a_noisy_tracker(cycles, seed):
    # 0.3 cm / 0.6 deg of step noise under 1 cm / 2 deg of tracker noise: it dominates every
    # stretch over about 20 steps, so dropping it made long runs look structured (the lag-0
    # and lag-1 moments alone gave 0.43 cm and 0 here)
    rng = np.random.default_rng(seed)
    runs = world_runs(measured_table().rows, [], cycles[:24], 200, rng, 1.0, 2.0,
                      step_noise_cm=0.3, step_noise_deg=0.6)
    nf = estimate_noise(batch_of(runs))
    assert nf.step_cm == pytest.approx(0.3, rel=0.35)
    assert nf.step_deg == pytest.approx(0.6, rel=0.35)
    assert nf.pos_cm == pytest.approx(1.0, rel=0.1)
    assert nf.heading_deg == pytest.approx(2.0, rel=0.1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_effect_free_mixed_runs_from_an_exact_start_are_not_flagged(seed):
    # the design that was flagged in 6 cases of 6: one power-on session of 24 runs of 40 to 79
    # gait cycles, the robot put down exactly on the start pose, 0.5 cm / 1 deg tracker noise
    rng = np.random.default_rng([64, seed])
    lengths = rng.integers(40, 80, 24).tolist()
    rows, fit, hold = blind_case(rng, [], lengths=lengths, start_exact=True,
                                 runs_per_session=24, pos_noise_cm=0.5, heading_noise_deg=1.0)
    d = diagnose(GaitTable(rows), fit, hold, rng, order=sorted(r.run_id for r in fit + hold))
    flags = d.unexplained["flags"] if d.unexplained else []
    assert d.verdict == "no_significant_gap" and not d.selected and not flags, (d.verdict, flags)
