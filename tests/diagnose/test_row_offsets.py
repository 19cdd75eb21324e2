"""Sequence and world effects judged beside an offset per row: rows fitted to noisy steps carry
an error, the same at every step of a row, that the selection took for a drift or a sag."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pac_host import cga, model_fit
from pac_host.coverage import simulate
from pac_host.diagnose.fit import with_row_offsets
from pac_host.diagnose.pipeline import _problems, select_effects
from pac_host.diagnose.residuals import batch_of
from pac_host.model import parse_effect, shifted_table
from pac_host.model.effects import EFFECT_SPECS

SEQUENCE = [n for n, sp in EFFECT_SPECS.items() if sp.stage != "table"]


def _noisy_runs(seed: int, effects=(), pos_sd: float = 0.5, head_sd: float = 1.0):
    """Nine runs of random short-loop turn cycles on the shifted table, poses observed with
    noise, split into fitting and held-out runs as the model correction splits them."""
    rng = np.random.default_rng(seed)
    pop = cga.random_population(rng, 9)
    pop[..., 1] = np.maximum(1, pop[..., 1] // 3)
    cov = simulate(shifted_table().rows, pop, 200, effects, keep_paths=True)
    obs = []
    for tc, poses in zip(pop, cov.poses, strict=True):
        p = np.array(poses, dtype=float)
        p[:, :2] += rng.normal(0, pos_sd, size=(len(p), 2))
        p[:, 2] += rng.normal(0, head_sd, size=len(p))
        obs.append(model_fit.Observed(model_fit.expand_ids(tc, 200)[: len(p) - 1], p))
    runs = model_fit._runs(obs)
    return model_fit.split_runs(runs, model_fit.HOLDOUT_FRACTION, rng)


def test_the_offsets_leave_residuals_orthogonal_to_every_used_row():
    fit, hold = _noisy_runs(0)
    free = model_fit._rows_only(shifted_table(), fit, ())
    _, prob, _ = _problems(free, batch_of(fit), batch_of(hold))
    with_off = with_row_offsets(prob)
    used = np.unique(prob.batch.ids[prob.batch.mask])
    assert with_off.nuisance.shape[1] == 3 * len(used)
    assert with_off.n_obs == prob.n_obs - 3 * len(used)
    w = with_off.whitened([])
    np.testing.assert_allclose(with_off.nuisance.T @ w, 0, atol=1e-8)
    # an offset on a used row is taken out whole: it changes no projected residual
    rows = free.rows.copy()
    rows[used[0]] += (0.4, -0.3, 0.7)
    np.testing.assert_allclose(replace(with_off, rows=rows).whitened([]), w, atol=1e-8)
    assert np.abs(replace(prob, rows=rows).whitened([]) - prob.whitened([])).max() > 0.1
    np.testing.assert_allclose(with_off.ssr_per_run([]).sum(), w @ w)


def test_noisy_poses_pass_no_sequence_or_world_effect_on_fitted_rows():
    # without the offsets, seeds 1 and 6 of these pass a floor slope (and a sag, a transition)
    passed = {}
    for seed in range(12):
        fit, hold = _noisy_runs(seed)
        free = model_fit._rows_only(shifted_table(), fit, ())
        plain = select_effects(free, fit, hold, SEQUENCE)
        fixed = select_effects(free, fit, hold, SEQUENCE, rows_fitted=True)
        passed[seed] = ([e.name for e in plain], [e.name for e in fixed])
    assert all(not fixed for _, fixed in passed.values()), passed
    assert sum(bool(plain) for plain, _ in passed.values()) >= 2, passed  # the case is real


@pytest.mark.parametrize("effect", ["transition:alpha=0.3", "battery_sag:beta=0.001",
                                    "floor_slope:s=0.1,theta=30"])
def test_a_true_effect_is_still_found_beside_the_offsets(effect):
    truth = parse_effect(effect)
    for seed in range(3):
        fit, hold = _noisy_runs(seed, (truth,))
        free = model_fit._rows_only(shifted_table(), fit, ())
        found = select_effects(free, fit, hold, SEQUENCE, rows_fitted=True)
        assert [e.name for e in found] == [truth.name], (seed, found)
