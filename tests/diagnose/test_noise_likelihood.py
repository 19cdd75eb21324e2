"""Noise floor estimate and the whitened likelihood it feeds."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.diagnose.likelihood import _substitute_numpy, whitener
from pac_host.diagnose.noise import NoiseFloor, estimate_noise
from pac_host.diagnose.residuals import batch_of, step_residuals
from pac_host.diagnose.synth import world_runs
from pac_host.model import Effect, measured_table

EFFECTS = [Effect("transition", {"alpha": 0.5}), Effect("turn_scale", {"c": 1.2})]


@pytest.mark.parametrize("pos, head", [(0.5, 1.0), (1.5, 0.5)])
def test_noise_floor_is_not_inflated_by_effects(make_runs, pos, head):
    b = batch_of(make_runs(EFFECTS, pos=pos, head=head))
    nf = estimate_noise(b)
    assert nf.reliable
    assert nf.pos_cm == pytest.approx(pos, rel=0.1)
    assert nf.heading_deg == pytest.approx(head, rel=0.1)


@pytest.mark.parametrize("step", [(0.0, 0.0), (0.3, 0.6)])
def test_whitened_residuals_of_the_true_model_are_white(cycles, step):
    rng = np.random.default_rng(4)
    runs = world_runs(measured_table().rows, EFFECTS, cycles[:30], 50, rng, 0.5, 1.0,
                      step_noise_cm=step[0], step_noise_deg=step[1])
    b = batch_of(runs)
    nf = NoiseFloor(0.5, 1.0, "true", 0, True, *step)  # the likelihood alone, known noise
    wh = whitener(b, nf)
    res = step_residuals(measured_table().rows, b, EFFECTS)
    w = wh.whiten(res)
    n = 3 * b.n_steps
    assert (w**2).sum() / n == pytest.approx(1.0, abs=0.06)
    # raw heading residuals are strongly anti-correlated step to step; whitened ones are not
    raw = res[..., 2][:, :-1] * res[..., 2][:, 1:]
    assert raw.mean() / (res[..., 2] ** 2).mean() < -0.3
    lag = (w[:, 3:] * w[:, :-3]).sum() / n
    assert abs(lag) < 0.05
    # without the effects the whitened sum of squares is far above its expectation
    assert wh.ssr_per_run(step_residuals(measured_table().rows, b, [])).sum() > 5 * n


def test_whitener_inverts_the_dense_covariance(make_runs):
    b = batch_of(make_runs([], n_runs=2, n_cycles=12))
    nf = NoiseFloor(0.5, 1.0, "given", 0, True, 0.3, 0.6)
    wh = whitener(b, nf)
    c = wh.n
    poses, o = b.poses[0, : c + 1], b.observed[0, :c]
    d = np.zeros((3 * c, 3 * (c + 1)))
    for i in range(c):
        h = np.radians(poses[i, 2])
        s, co = np.sin(h), np.cos(h)
        d[3 * i, 3 * i : 3 * i + 5] = [-s, -co, np.radians(o[i, 1]), s, co]
        d[3 * i + 1, 3 * i : 3 * i + 5] = [-co, s, -np.radians(o[i, 0]), co, -s]
        d[3 * i + 2, [3 * i + 2, 3 * i + 5]] = [-1, 1]
    var = np.tile([nf.pos_cm**2, nf.pos_cm**2, nf.heading_deg**2], c + 1)
    # the step noise, and the second-order part: heading noise turning the position noise
    turn = np.radians(nf.heading_deg) ** 2 * 2 * nf.pos_cm**2
    sigma = (d * var) @ d.T + np.diag(np.tile([nf.step_cm**2 + turn, nf.step_cm**2 + turn,
                                               nf.step_deg**2], c))
    w = wh.w[0]
    np.testing.assert_allclose(w @ sigma @ w.T, np.eye(3 * c), atol=1e-9)


def test_noise_floor_separates_the_robots_own_step_noise(cycles):
    rng = np.random.default_rng(5)
    runs = world_runs(measured_table().rows, EFFECTS, cycles, 60, rng, 0.5, 1.0,
                      step_noise_cm=0.4, step_noise_deg=1.0)
    nf = estimate_noise(batch_of(runs))
    assert nf.pos_cm == pytest.approx(0.5, rel=0.15)
    assert nf.heading_deg == pytest.approx(1.0, rel=0.15)
    assert nf.step_cm == pytest.approx(0.4, rel=0.35)
    assert nf.step_deg == pytest.approx(1.0, rel=0.35)
    # and effect-free data from such a robot are not mistaken for a gap
    from pac_host.diagnose import diagnose, split_runs
    from pac_host.model import GaitTable

    runs = world_runs(measured_table().rows, [], cycles, 60, rng, 0.5, 1.0,
                      step_noise_cm=0.4, step_noise_deg=1.0)
    fit, hold = split_runs(runs, 0.3, rng)
    d = diagnose(GaitTable(measured_table().rows), fit, hold, rng)
    assert d.verdict == "no_significant_gap" and d.selected == []


def test_block_substitution_whitens_as_the_dense_inverse(make_runs):
    """The fast whitening (block forward substitution, compiled or numpy) gives the dense
    L^-1 r value for value, along whole runs of 150 steps, and with leading dimensions."""
    b = batch_of(make_runs([], n_runs=3, n_cycles=150))
    wh = whitener(b, NoiseFloor(0.5, 1.0, "given", 0, True, 0.3, 0.6))
    res = np.random.default_rng(2).normal(size=(2, *b.ids.shape, 3))
    fast, dense = wh.whiten(res), wh.whiten(res, dense=True)
    assert fast.shape == dense.shape == (2, 3, 3 * 150)
    np.testing.assert_allclose(fast, dense, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(wh.whiten(res[0]), dense[0], rtol=1e-10, atol=1e-10)
    loop = _substitute_numpy(wh.linv, wh.sub, res).reshape(dense.shape)
    np.testing.assert_allclose(loop, dense, rtol=1e-10, atol=1e-10)
