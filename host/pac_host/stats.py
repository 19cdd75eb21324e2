"""Small exact tests for comparing the two recombination methods over seeds (no SciPy needed).

>>> round(fisher_exact(5, 0, 1, 4), 4)  # the paper's 5/5 against 1/5
0.0476
>>> wilcoxon_signed_rank([3, 4, 5, 6, 7], [1, 2, 3, 4, 5])["p_value"]  # all five pairs favour x
0.0625
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def fisher_exact(a: int, b: int, c: int, d: int) -> float:
    """Two-sided Fisher exact p-value of the 2x2 table [[a, b], [c, d]]
    (rows: methods; columns: reached the optimum, did not)."""
    r1, r2, c1, n = a + b, c + d, a + c, a + b + c + d

    def prob(x: int) -> float:
        return math.comb(r1, x) * math.comb(r2, c1 - x) / math.comb(n, c1)

    p_obs = prob(a)
    lo, hi = max(0, c1 - r2), min(r1, c1)
    return min(1.0, sum(p for x in range(lo, hi + 1) if (p := prob(x)) <= p_obs * (1 + 1e-9)))


def wilcoxon_signed_rank(x: Sequence[float], y: Sequence[float]) -> dict:
    """Paired two-sided Wilcoxon signed-rank test of x against y (zero differences dropped).

    Exact null distribution of the rank sum (average ranks for ties, enumerated over sign
    patterns by dynamic programming on doubled ranks), so it is valid for the few seeds used.
    """
    d = np.asarray(x, dtype=float) - np.asarray(y, dtype=float)
    d = d[d != 0]
    n = len(d)
    if n == 0:
        return {"n": 0, "statistic": 0.0, "p_value": 1.0}
    absd = np.abs(d)
    order = np.argsort(absd, kind="stable")
    ranks = np.empty(n)
    ranks[order] = np.arange(1, n + 1)
    for v in np.unique(absd):  # average ranks of ties
        tie = absd == v
        ranks[tie] = ranks[tie].mean()
    w_plus = float(ranks[d > 0].sum())
    r2 = np.rint(ranks * 2).astype(int)  # ranks are multiples of 1/2
    total = int(r2.sum())
    dist = np.zeros(total + 1)
    dist[0] = 1.0
    for r in r2:
        dist[r:] = dist[r:] + dist[: total + 1 - r].copy()
    dist /= dist.sum()
    w2 = int(round(w_plus * 2))
    mean2 = total / 2
    dev = abs(w2 - mean2)
    k = np.arange(total + 1)
    p = float(dist[np.abs(k - mean2) >= dev - 1e-9].sum())
    return {"n": n, "statistic": w_plus, "p_value": min(1.0, p)}
