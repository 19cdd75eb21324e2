"""Tests and intervals of the diagnosis, on top of :mod:`scipy.stats`.

What is the project's own here is the held-out projection test (the statistic, and why it is
normal under "no effect"); the tails and the bootstrap are SciPy's.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import stats as sps


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
    return z, float(sps.norm.sf(z))


def _ratio_shrink(num: np.ndarray, den: np.ndarray, axis: int = -1) -> np.ndarray:
    s_den = den.sum(axis=axis)
    return 1.0 - num.sum(axis=axis) / np.where(s_den > 0, s_den, np.nan)


def bootstrap_ratio_ci(
    num: np.ndarray, den: np.ndarray, rng: np.random.Generator, n_boot: int = 2000,
    level: float = 0.95,
) -> tuple[float, float]:
    """Percentile interval of 1 - sum(num) / sum(den) over runs resampled with replacement
    (pairs (num_i, den_i) kept together: ``scipy.stats.bootstrap`` with ``paired=True``)."""
    if len(num) == 0:
        return (float("nan"), float("nan"))
    if len(num) == 1:  # one held-out run: every resample is that run
        v = float(_ratio_shrink(np.asarray(num), np.asarray(den)))
        return (v, v)
    with warnings.catch_warnings():  # resamples with no held-out move: NaN, said by the result
        warnings.simplefilter("ignore", sps.DegenerateDataWarning)
        res = sps.bootstrap((np.asarray(num, float), np.asarray(den, float)), _ratio_shrink,
                            n_resamples=n_boot, paired=True, vectorized=True,
                            confidence_level=level, method="percentile", rng=rng)
    ci = res.confidence_interval
    return float(ci.low), float(ci.high)
