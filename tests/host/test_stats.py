"""The tests that compare methods, checked against hand-computed values and brute-force
enumeration of their null distributions (the cases the hand-written versions were checked on)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pac_host.experiments.stats import fisher_exact, wilcoxon_signed_rank


def _fisher_by_enumeration(a: int, b: int, c: int, d: int) -> float:
    r1, r2, c1, n = a + b, c + d, a + c, a + b + c + d

    def prob(x: int) -> float:
        return math.comb(r1, x) * math.comb(r2, c1 - x) / math.comb(n, c1)

    p_obs = prob(a)
    xs = range(max(0, c1 - r2), min(r1, c1) + 1)
    return min(1.0, sum(p for x in xs if (p := prob(x)) <= p_obs * (1 + 1e-9)))


def test_fisher_exact_known_values():
    # paper's 5/5 vs 1/5: p = 2 * C(5,5)C(5,1)/C(10,6) = 2 * 5/210
    assert fisher_exact(5, 0, 1, 4) == pytest.approx(10 / 210, abs=1e-12)
    assert fisher_exact(3, 3, 3, 3) == pytest.approx(1.0, abs=1e-12)
    assert fisher_exact(30, 0, 0, 30) == pytest.approx(2 / math.comb(60, 30), rel=1e-9)


@pytest.mark.parametrize("table", [(12, 18, 7, 23), (11, 19, 3, 27), (0, 30, 1, 29),
                                   (13, 17, 7, 23), (2, 3, 9, 1)])
def test_fisher_exact_equals_enumeration(table):
    assert fisher_exact(*table) == pytest.approx(_fisher_by_enumeration(*table), abs=1e-9)


def _wilcoxon_by_enumeration(x, y) -> tuple[float, float]:
    d = np.asarray(x, float) - np.asarray(y, float)
    d = d[d != 0]
    absd = np.abs(d)
    ranks = np.array([np.mean(np.where(np.sort(absd) == v)[0] + 1) for v in absd])
    w = ranks[d > 0].sum()
    mean = ranks.sum() / 2
    sums = [sum(r for r, s in zip(ranks, signs, strict=True) if s)
            for signs in itertools.product([0, 1], repeat=len(ranks))]
    return w, float(np.mean([abs(s - mean) >= abs(w - mean) - 1e-9 for s in sums]))


def _tied_integers(rng):
    return rng.integers(0, 10, 9).astype(float), rng.integers(0, 10, 9).astype(float)


def _distinct_reals(rng):
    x = rng.normal(size=12)
    return x, x + rng.normal(0.4, 1.0, 12)


@pytest.mark.parametrize(("pairs", "method"), [(_tied_integers, "permutation"),
                                               (_distinct_reals, "exact")])
def test_wilcoxon_matches_brute_force_enumeration(pairs, method):
    x, y = pairs(np.random.default_rng(0))
    got = wilcoxon_signed_rank(x, y)
    w, p = _wilcoxon_by_enumeration(x, y)
    assert got["method"] == method
    assert got["statistic"] == pytest.approx(w)
    assert got["p_value"] == pytest.approx(p, abs=1e-9)


def test_wilcoxon_30_tied_seeds_all_one_way_is_the_exact_tail():
    # 30 seeds of integer coverage, x higher on every seed: exactly 2 of 2^30 sign patterns
    # are as extreme, whatever the ties (the normal approximation would say ~1e-6)
    rng = np.random.default_rng(2)
    y = rng.integers(5, 25, 30)
    x = y + rng.integers(1, 4, 30)
    got = wilcoxon_signed_rank(x, y)
    assert got["method"] == "exact"
    assert got["p_value"] == pytest.approx(2 / 2**30, rel=1e-9)
    assert wilcoxon_signed_rank(y, x)["p_value"] == pytest.approx(got["p_value"], rel=1e-12)


def test_wilcoxon_beyond_50_pairs_uses_the_normal_approximation():
    rng = np.random.default_rng(3)
    y = rng.integers(5, 25, 80)
    x = y + rng.integers(-2, 6, 80)
    got = wilcoxon_signed_rank(x, y)
    assert got["method"] == "normal" and got["p_value"] < 0.01


def test_wilcoxon_no_difference():
    assert wilcoxon_signed_rank([1, 2, 3], [1, 2, 3])["p_value"] == 1.0
