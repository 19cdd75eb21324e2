"""The smooth prior over row offsets: its algebra, when it is chosen, what it teaches."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.stats import multivariate_normal

from pac_host.learning import model_fit, pal, row_prior
from pac_host.model import measured_table
from pac_host.model.table import GaitTable, side, strength
from pac_host.search import cga


def _steps(rng, ids, offsets, noise, per_row=15):
    design = np.eye(32)[np.repeat(ids, per_row)]
    return design, design @ offsets + rng.normal(scale=noise, size=len(design))


def test_log_evidence_is_the_marginal_likelihood_of_the_steps():
    rng = np.random.default_rng(2)
    design, resid = _steps(rng, np.arange(0, 32, 3), rng.normal(size=32), 0.4, per_row=3)
    gram, xty = design.T @ design, design.T @ resid
    Ks = [row_prior.kernel(0.5, 1.2, 3.0, 0.3), row_prior.kernel(0.2, 0.0, 1.0, 0.0)]
    direct = [multivariate_normal(np.zeros(len(resid)), 0.16 * np.eye(len(resid))
                                  + design @ K @ design.T).logpdf(resid) for K in Ks]
    mine = [row_prior.log_evidence(K, gram, xty, 0.4) for K in Ks]
    assert mine[0] - mine[1] == pytest.approx(direct[0] - direct[1], rel=1e-9)
    mean, cov = row_prior.posterior(Ks[0], gram, xty, 0.4)
    want = np.linalg.inv(np.linalg.inv(Ks[0]) + gram / 0.16)
    assert np.allclose(cov, want) and np.allclose(mean, want @ xty / 0.16)


def test_independent_offsets_keep_the_independent_prior():
    for seed in range(5):
        rng = np.random.default_rng(seed)
        design, resid = _steps(rng, rng.choice(32, 14, replace=False), rng.normal(size=32), 0.2)
        assert row_prior.smooth_prior(design.T @ design, design.T @ resid, 0.2, 1.0) is None


def _one_side_worn():
    """A wrong leg on one side: strides shorten and headings stretch as that side's turn gets
    harder, smoothly, and like no effect of the library. Returns the starting table, the
    robot's rows and four observed tests."""
    ids = np.arange(32)
    hard = (15 - strength(ids)) * (side(ids) == 1)
    base = measured_table()
    rows = base.rows.copy()
    rows[:, 0] -= 0.06 * hard
    rows[:, 2] *= 1 + 0.01 * hard
    tests = cga.random_population(np.random.default_rng(5), 4)
    tests[..., 1] //= 4
    res = pal.SimulatedRobot(GaitTable(rows, (), "one_side_worn")).run_tests(tests)
    obs = [model_fit.Observed(model_fit.expand_ids(t, 200), r.poses)
           for t, r in zip(tests, res, strict=True)]
    return base, rows, obs


def test_offsets_smooth_in_the_turn_strength_reach_the_rows_never_walked():
    base, rows, obs = _one_side_worn()
    post = model_fit.correct(base, obs, np.random.default_rng(0), structure="none")
    unused = post.evidence == 0
    assert unused.sum() >= 6
    err = np.abs(post.mean - rows)[unused][:, [0, 2]].mean(axis=0)
    err_base = np.abs(base.rows - rows)[unused][:, [0, 2]].mean(axis=0)
    assert np.all(err < 0.4 * err_base)


def test_without_the_smooth_prior_the_rows_never_walked_stay(monkeypatch):
    # the same robot with the smooth prior switched off: what the test above gains is its doing
    monkeypatch.setattr(row_prior, "MIN_GAIN", np.inf)
    base, _, obs = _one_side_worn()
    post = model_fit.correct(base, obs, np.random.default_rng(0), structure="none")
    unused = post.evidence == 0
    assert np.abs(post.mean - base.rows)[unused].max() < 1e-9


def test_the_smooth_fit_reaches_its_optimum_on_near_noise_free_steps(monkeypatch):
    # simulated steps are near noise-free, so the evidence runs to hundreds of millions of
    # nats: a search stopping on a change relative to that, or on a finite-difference gradient
    # below its rounding noise, stopped nats short of the optimum, by a machine-dependent margin
    problems = []
    fit = row_prior.smooth_prior

    def spy(gram, xty, sigma, scale, floor=0.0):
        K = fit(gram, xty, sigma, scale, floor)
        problems.append(((gram, xty, sigma, scale, floor), K))
        return K

    monkeypatch.setattr(row_prior, "smooth_prior", spy)
    base, _, obs = _one_side_worn()
    model_fit.correct(base, obs, np.random.default_rng(0), structure="none")
    assert len(problems) == 3 and problems[2][0][2] < 0.01   # dH, steps near noise-free
    (gram, xty, sigma, scale, floor), K = problems[2]
    assert K is not None

    def loss(x):
        a, b, length = np.exp(x[:3])
        return -row_prior.log_evidence(row_prior.kernel(a, b, length, x[3]), gram, xty, sigma)

    bounds = [(np.log(max(floor, 1e-3 * scale)), np.log(3 * scale)),
              (np.log(1e-3 * scale), np.log(3 * scale)), tuple(np.log(row_prior.LENGTH)),
              (0.0, 1.0)]
    polished = min(minimize(loss, np.array([np.log(0.1 * scale), np.log(0.5 * scale),
                                            np.log(ell), 0.5]),
                            method="Nelder-Mead", bounds=bounds,
                            options={"xatol": 1e-7, "fatol": 1e-9, "maxfev": 5000}).fun
                   for ell in (2.0, 8.0))
    assert -row_prior.log_evidence(K, gram, xty, sigma) < polished + 0.05
