"""Judging sequence and world effects on rows fitted to the same noisy steps.

When the table's rows are not known but fitted to the runs (the model correction of every
punctuation fits the rows the tests used to their steps), a row's estimation error is the
same at every step that uses it, and on a held-out run it adds up along the run like a drift
or a sag. Taking the fitted rows as exact then passes such effects at a rate far above the
test's level (at 0.5 cm / 1 deg of pose noise, nine runs: a floor slope in 16 of 100 trials,
a battery sag in 8). The pair of problems built here treats the rows as what they are:

- On the fitting runs, each effect is fitted jointly with an offset per used row and
  component (generalised least squares, the rows profiled out: the whitened residual is
  projected off the whitened row columns, Frisch-Waugh-Lovell), so an effect is only what the
  rows cannot take up, and the likelihood-ratio and BIC count the rows' parameters.
- On the held-out runs, the rows are the ones re-fitted beside the effect (so a sag that
  the rows had partly absorbed is judged with the rows that go with it), and the residuals are
  whitened with the rows' estimation error added to the steps' noise: the error e of the
  fitted rows has covariance C = (X^T X)^-1 in whitened units (X the fitting runs' whitened row
  columns), so a held-out run's whitened residual has covariance I + V V^T, V = X_h C^(1/2);
  its inverse square root is applied through the SVD of V. A row the fitting runs never used
  is free (its offset is taken out of the held-out residual entirely).

The held-out projection test of :mod:`.select` is then valid again (the whitened held-out
residual is noise of unit variance under "no effect") without throwing away what a short
held-out run shows: only the part of it the rows' error can explain is discounted, by as much
as that error is large.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pac_host.diagnose.fit import Problem
from pac_host.diagnose.residuals import Batch, row_design, step_residuals
from pac_host.model.effects import Effect

FREE_SCALE = 1e4  # a row with no fitting evidence: sd of its offset in whitened units
RANK_TOL = 1e-10


def _row_columns(prob: Problem, keys: list[tuple[int, int]]) -> np.ndarray:
    """Whitened d(predicted step) / d(row g, component c) for each (g, c) in ``keys``: (n, k),
    under the problem's own effects (:func:`~pac_host.diagnose.residuals.row_design`)."""
    b = prob.batch
    design = row_design(b, prob.base_effects) if keys else None
    cols = np.zeros((len(keys),) + b.ids.shape + (3,))
    for i, (g, c) in enumerate(keys):
        cols[i][..., c] = design[..., g]
    return prob.whitener.whiten(cols).reshape(len(keys), -1).T


def _used(batch: Batch) -> np.ndarray:
    return np.unique(batch.ids[batch.mask]).astype(np.int64)


def fitted_rows_problems(fit_p: Problem, hold_p: Problem) -> tuple[Problem, Problem]:
    """The (fitting, held-out) problems ``fit_p`` and ``hold_p``, for rows used by the fitting
    runs that were estimated from them (see the module's docstring)."""
    base, fit_b, hold_b, fit_w = fit_p.base_effects, fit_p.batch, hold_p.batch, fit_p.whitener
    used = _used(fit_b)
    keys = [(int(g), c) for g in used for c in range(3)]
    x = _row_columns(fit_p, keys)
    lam, p = np.linalg.eigh(x.T @ x)
    keep = lam > RANK_TOL * max(float(lam.max(initial=0.0)), 1e-300)
    p, lam = p[:, keep], lam[keep]
    q = x @ p / np.sqrt(lam)  # orthonormal basis of the whitened row columns
    gls = p @ ((p.T @ x.T) / lam[:, None])  # (k, n): whitened residual -> row offsets
    gi, ci = np.array([k[0] for k in keys], dtype=np.int64), np.array([k[1] for k in keys],
                                                                      dtype=np.int64)

    def refit(rows: np.ndarray, effects: tuple[Effect, ...]) -> np.ndarray:
        # one Gauss-Newton step on the rows: exact where the tried effects leave the rows'
        # columns as they are (drifts, offsets), close for a transition or sag on top
        w = fit_w.whiten(step_residuals(rows, fit_b, base + effects)).ravel()
        out = rows.copy()
        out[gi, ci] += gls @ w
        return out

    rows0 = refit(np.asarray(fit_p.rows, dtype=np.float64), ())

    def rows_for(effects: tuple[Effect, ...]) -> np.ndarray:
        return rows0 if not effects else refit(rows0, effects)

    fit_out = replace(fit_p, rows=rows0, correlated=(q, np.ones(q.shape[1])),
                      dof_taken=q.shape[1])
    # held-out: the fitted rows' error (covariance C = P diag(1/lam) P^T) and free rows
    free = [(int(g), c) for g in np.setdiff1d(_used(hold_b), used) for c in range(3)]
    xh = _row_columns(hold_p, keys + free)
    v = np.hstack([xh[:, : len(keys)] @ p / np.sqrt(lam), FREE_SCALE * xh[:, len(keys):]])
    if v.shape[1]:
        u, s, _ = np.linalg.svd(v, full_matrices=False)
        big = s > RANK_TOL * max(float(s.max()), 1e-300)
        u, s = u[:, big], s[big]
    else:
        u, s = v, np.zeros(0)
    f = 1.0 - 1.0 / np.sqrt(1.0 + s**2)
    hold_out = replace(hold_p, rows=rows0, rows_for=rows_for, correlated=(u, f),
                       dof_taken=min(len(free), len(s)))
    return fit_out, hold_out
