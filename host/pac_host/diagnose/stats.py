"""Small distribution helpers (no scipy): chi-square and normal tails, bootstrap intervals."""

from __future__ import annotations

import math

import numpy as np


def normal_sf(z: float) -> float:
    """P(Z > z) for a standard normal Z."""
    return 0.5 * math.erfc(z / math.sqrt(2.0))


def _gammainc_upper(a: float, x: float) -> float:
    """Regularized upper incomplete gamma Q(a, x) (series or continued fraction)."""
    if x <= 0:
        return 1.0
    lg = math.lgamma(a)
    if x < a + 1:
        term = total = 1.0 / a
        ap = a
        for _ in range(1000):
            ap += 1
            term *= x / ap
            total += term
            if abs(term) < abs(total) * 1e-15:
                break
        return max(0.0, 1.0 - total * math.exp(-x + a * math.log(x) - lg))
    b = x + 1 - a
    c = 1e300
    d = 1 / b
    h = d
    for i in range(1, 1000):
        an = -i * (i - a)
        b += 2
        d = an * d + b
        d = 1e-300 if abs(d) < 1e-300 else d
        c = b + an / c
        c = 1e-300 if abs(c) < 1e-300 else c
        d = 1 / d
        delta = d * c
        h *= delta
        if abs(delta - 1) < 1e-15:
            break
    return math.exp(-x + a * math.log(x) - lg) * h


def chi2_sf(x: float, df: float) -> float:
    """P(X > x) for X chi-square with ``df`` degrees of freedom."""
    return _gammainc_upper(df / 2.0, max(x, 0.0) / 2.0)


def projection_p(before: np.ndarray, after: np.ndarray, sigma2: float) -> tuple[float, float]:
    """One-sided test that the change from ``before`` to ``after`` whitened residuals is real.

    With d = before - after (the whitened change of prediction, fixed before looking at these
    data), under "no effect" ``before`` is noise of variance sigma2, so ``before . d`` is
    N(0, sigma2 |d|^2). Returns (z, p).
    """
    d = before - after
    nd = float(np.sqrt(np.dot(d, d)))
    if nd == 0.0:
        return 0.0, 1.0
    z = float(np.dot(before, d)) / (math.sqrt(sigma2) * nd)
    return z, normal_sf(z)


def bootstrap_ratio_ci(
    num: np.ndarray, den: np.ndarray, rng: np.random.Generator, n_boot: int = 2000,
    level: float = 0.95,
) -> tuple[float, float]:
    """Percentile interval of 1 - sum(num) / sum(den) over runs resampled with replacement."""
    k = len(num)
    if k == 0:
        return (float("nan"), float("nan"))
    idx = rng.integers(0, k, size=(n_boot, k))
    s_den = den[idx].sum(axis=1)
    s_num = num[idx].sum(axis=1)
    shrink = 1.0 - s_num / np.where(s_den > 0, s_den, np.nan)
    lo, hi = np.nanquantile(shrink, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)
