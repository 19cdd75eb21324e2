"""The prior over a table's row offsets, fitted to the observed steps (empirical Bayes).

The whole-table correction (:mod:`pac_host.learning.model_fit`) estimates, per component (F, T,
dH), an
offset for each of the 32 rows by Bayesian linear regression. The plain prior makes the
offsets independent, ``N(0, a^2 I)``: an unused row stays where the structure put it. A robot
can also be wrong in a way no effect of the library names, yet smoothly across its gait cycles
(a stride that shortens as the turn gets harder, a heading change that stretches with it).
The *smooth* prior adds a part shared by gait cycles of similar turn strength:

    K = a^2 I + b^2 S,   S[i, j] = exp(-(s_i - s_j)^2 / (2 l^2)) * (1 if same side else rho)

(``s``: turn strength 0-15, side: left or right turn), so the rows the tests walked say
something about their untested neighbours. Its four parameters are fitted by the marginal
likelihood of the observed steps, and it is used only when it explains them better than the
independent prior by :data:`MIN_GAIN` nats: on a robot whose rows are wrong each on its own the
correction is what it was.

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> design = np.eye(32)[::2].repeat(20, axis=0)          # the even gait ids, 20 steps each
>>> truth = 0.3 * (np.arange(32) & 15)                   # smooth in the turn strength
>>> resid = design @ truth + rng.normal(scale=0.1, size=len(design))
>>> K = smooth_prior(design.T @ design, design.T @ resid, 0.1, 1.0)
>>> mean, cov = posterior(K, design.T @ design, design.T @ resid, 0.1)
>>> bool(np.abs(mean - truth)[1::2].max() < 0.5)         # the odd ids, never walked
True
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from pac_host.model.table import N_IDS, side, strength

MIN_GAIN = 4.0  # nats of marginal likelihood the smooth prior must add over the independent one
_IDS = np.arange(N_IDS)
_DS2 = (strength(_IDS)[:, None] - strength(_IDS)[None, :]).astype(np.float64) ** 2
_SAME = side(_IDS)[:, None] == side(_IDS)[None, :]
LENGTH = (0.5, 30.0)  # bounds of the length scale, in steps of turn strength


def kernel(a: float, b: float, length: float, rho: float) -> np.ndarray:
    """The prior covariance of the 32 row offsets (see the module docstring)."""
    return a * a * np.eye(N_IDS) + b * b * _shared(_decay(length), rho)


def _decay(length: float) -> np.ndarray:
    """exp(-(s_i - s_j)^2 / (2 l^2)): how alike two rows' offsets are by turn strength."""
    return np.exp(-_DS2 / (2.0 * length * length))


def _shared(decay: np.ndarray, rho: float) -> np.ndarray:
    """The shared part S of the prior: ``decay``, times ``rho`` across turn sides."""
    return decay * np.where(_SAME, 1.0, rho)


def _whitened(K: np.ndarray, gram: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """K's Cholesky factor L and M = I + L' X'X L / sigma^2, the posterior in whitened offsets
    (both the evidence and the posterior are read from them)."""
    L = np.linalg.cholesky(K)
    return L, np.eye(N_IDS) + L.T @ gram @ L / sigma**2


def _evidence_parts(K: np.ndarray, gram: np.ndarray, xty: np.ndarray, sigma: float):
    """L, M (:func:`_whitened`), M's Cholesky factor C, z = C^-1 L' X'r and the log evidence
    (:func:`log_evidence`), which the gradient reuses."""
    L, M = _whitened(K, gram, sigma)
    C = np.linalg.cholesky(M)
    z = np.linalg.solve(C, L.T @ xty)
    return L, M, C, z, 0.5 * float(z @ z) / sigma**4 - float(np.log(np.diag(C)).sum())


def log_evidence(K: np.ndarray, gram: np.ndarray, xty: np.ndarray, sigma: float) -> float:
    """The log marginal likelihood of the residuals, up to terms that do not depend on ``K``:
    residuals ``r = X o + e``, ``o ~ N(0, K)``, ``e ~ N(0, sigma^2)``; ``gram`` = X'X and
    ``xty`` = X'r. Computed in the 32 offsets (Woodbury), never in the steps."""
    return _evidence_parts(K, gram, xty, sigma)[-1]


def _evidence_grad(K: np.ndarray, gram: np.ndarray, xty: np.ndarray, sigma: float
                   ) -> tuple[float, np.ndarray]:
    """:func:`log_evidence` and its gradient W with respect to the prior covariance
    (d log p = tr(W dK)): W = (K^-1 (S + m m') K^-1 - K^-1) / 2 for the posterior mean m and
    covariance S, computed as (v v' - K^-1 S X'X / sigma^2) / 2 with v = K^-1 m, from the
    Cholesky factors the evidence uses (no inverse of K is formed)."""
    L, M, C, z, value = _evidence_parts(K, gram, xty, sigma)
    # (numpy's solve on the 32 x 32 factors: scipy.linalg's triangular solves cost far more
    # in their checks and wrappers than in the arithmetic at this size)
    u = np.linalg.solve(C.T, z) / sigma**2     # M^-1 L' X'r / sigma^2
    v = np.linalg.solve(L.T, u)                # K^-1 m
    ks = np.linalg.solve(L.T, np.linalg.solve(M, L.T))  # K^-1 S = L^-T M^-1 L'
    W = np.outer(v, v) - ks @ gram / sigma**2
    return value, 0.5 * (W + W.T) / 2.0


def posterior(K: np.ndarray, gram: np.ndarray, xty: np.ndarray, sigma: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """Posterior mean and covariance of the offsets under the prior ``K``."""
    L, M = _whitened(K, gram, sigma)
    cov = L @ np.linalg.solve(M, L.T)
    cov = 0.5 * (cov + cov.T)
    return cov @ xty / sigma**2, cov


def _best(objective, starts, bounds) -> tuple[np.ndarray, float]:
    """The best of L-BFGS-B runs from ``starts``; ``objective`` returns its value and gradient.
    It must be small near its minimum (measured from a reference, as the gain over the
    independent prior is): the method stops on a change of ``f`` relative to ``|f|``, which
    on the raw evidence of near noise-free steps (hundreds of millions of nats) is a nat or
    more, more than the gain it is judging. The gradient is exact (:func:`_evidence_grad`):
    a finite-difference one cost five evidences a step, and below a step of 1e-5 it was the
    evidence's rounding noise."""
    best_x, best_f = None, np.inf
    for x0 in starts:
        res = minimize(objective, np.asarray(x0, dtype=np.float64), method="L-BFGS-B",
                       bounds=bounds, jac=True)
        if res.fun < best_f:
            best_x, best_f = res.x, float(res.fun)
    return best_x, best_f


def _best_scalar(objective, lo: float, hi: float, points: int = 25) -> tuple[float, float]:
    """The minimum of a function of one bounded parameter: the best of a grid, refined by
    bounded Brent between its neighbours. Function values only: with near noise-free steps the
    evidence runs to hundreds of millions of nats, where a finite-difference gradient is
    rounding noise and a gradient method stops wherever (the independent prior then looked
    several nats worse than it is, and the smooth prior won by that margin alone)."""
    grid = np.linspace(lo, hi, points)
    f = np.array([objective(np.array([g])) for g in grid])
    i = int(np.argmin(f))
    res = minimize_scalar(lambda t: objective(np.array([t])), method="bounded",
                          bounds=(grid[max(i - 1, 0)], grid[min(i + 1, points - 1)]),
                          options={"xatol": 1e-8})
    return (float(res.x), float(res.fun)) if res.fun < f[i] else (float(grid[i]), float(f[i]))


def smooth_prior(gram: np.ndarray, xty: np.ndarray, sigma: float, scale: float,
                 floor: float = 0.0) -> np.ndarray | None:
    """The smooth prior's covariance fitted to the steps, or None when it does not beat the
    independent prior (fitted the same way) by :data:`MIN_GAIN` nats. ``scale``: the prior
    spread the table starts with (bounds the fit); ``floor``: the least independent spread."""
    lo_a = np.log(max(floor, 1e-3 * scale))
    hi = np.log(3.0 * scale)

    def iid(x):
        return -log_evidence(kernel(np.exp(x[0]), 0.0, 1.0, 0.0), gram, xty, sigma)

    ia, f_iid = _best_scalar(iid, lo_a, hi)

    def loss(x):  # minus the smooth prior's gain over the fitted independent prior, in nats
        a, b, length = np.exp(x[:3])
        decay = _decay(length)
        shared = _shared(decay, float(x[3]))
        value, W = _evidence_grad(a * a * np.eye(N_IDS) + b * b * shared, gram, xty, sigma)
        # dK over the log of a, b and the length scale, and over rho
        grad = np.array([2.0 * a * a * np.trace(W), 2.0 * b * b * np.sum(W * shared),
                         b * b * np.sum(W * shared * _DS2) / (length * length),
                         b * b * np.sum(W * np.where(_SAME, 0.0, decay))])
        return -value - f_iid, -grad

    bounds = [(lo_a, hi), (np.log(1e-3 * scale), hi), tuple(np.log(LENGTH)), (0.0, 1.0)]
    starts = [[ia, np.log(0.5 * scale), np.log(ell), rho] for ell in (2.0, 8.0)
              for rho in (0.0, 1.0)]
    x, least = _best(loss, starts, bounds)
    if -least < MIN_GAIN:
        return None
    a, b, length = np.exp(x[:3])
    return kernel(a, b, length, float(x[3]))
