"""Exact tests used to compare the methods, checked against hand-computed values."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pac_host.stats import fisher_exact, wilcoxon_signed_rank


def test_fisher_exact_known_values():
    # paper's 5/5 vs 1/5: p = 2 * C(5,5)C(5,1)/C(10,6) = 2 * 5/210
    assert fisher_exact(5, 0, 1, 4) == pytest.approx(10 / 210)
    assert fisher_exact(3, 3, 3, 3) == pytest.approx(1.0)
    assert fisher_exact(30, 0, 0, 30) == pytest.approx(2 / math.comb(60, 30))


def test_wilcoxon_matches_brute_force_enumeration():
    rng = np.random.default_rng(0)
    x = rng.integers(0, 10, 9).astype(float)
    y = rng.integers(0, 10, 9).astype(float)
    got = wilcoxon_signed_rank(x, y)
    d = x - y
    d = d[d != 0]
    absd = np.abs(d)
    ranks = np.array([np.mean(np.where(np.sort(absd) == v)[0] + 1) for v in absd])
    w = ranks[d > 0].sum()
    mean = ranks.sum() / 2
    sums = [sum(r for r, s in zip(ranks, signs, strict=True) if s)
            for signs in itertools.product([0, 1], repeat=len(ranks))]
    p = np.mean([abs(s - mean) >= abs(w - mean) - 1e-9 for s in sums])
    assert got["statistic"] == pytest.approx(w)
    assert got["p_value"] == pytest.approx(p)


def test_wilcoxon_no_difference():
    assert wilcoxon_signed_rank([1, 2, 3], [1, 2, 3])["p_value"] == 1.0
