"""The compiled coverage kernel against the numpy simulator, the reference: value for value."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host import cga, coverage_jit
from pac_host.coverage import simulate
from pac_host.model import measured_table, parse_effect, shifted_table

pytestmark = pytest.mark.skipif(not coverage_jit.AVAILABLE, reason="numba not installed")
FIGURES = ("blocks_covered", "blocks_covered_once", "fitness", "repeat_visits")


def _population(rng: np.random.Generator, n: int) -> np.ndarray:
    pop = cga.random_population(rng, n)
    short = rng.random(pop.shape[:2]) < 0.5  # short genes too: loops that repeat many times
    pop[..., 1] = np.where(short, pop[..., 1] // 8, pop[..., 1])
    pop[:8, :, 1] = 0  # turn cycles that stand still
    pop[8:16, 1:, 1] = 0  # a single gene
    return pop


def _same(a, b) -> None:
    for f in FIGURES:
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)


@pytest.mark.parametrize("budget", [0, 1, 37, 200, 450])
def test_kernel_equals_numpy_on_random_turn_cycles(budget):
    rng = np.random.default_rng(budget)
    pop = _population(rng, 3000)
    for rows in (measured_table().rows, shifted_table().rows,
                 measured_table().rows + rng.normal(0, 0.8, (32, 3))):
        _same(simulate(rows, pop, budget, kernel="numba"),
              simulate(rows, pop, budget, kernel="numpy"))


def test_kernel_equals_numpy_on_many_tables_and_with_effects():
    rng = np.random.default_rng(1)
    pop = _population(rng, 40)
    models = measured_table().rows + rng.normal(0, 0.6, (50, 32, 3))
    _same(simulate(models, pop, 200, kernel="numba"), simulate(models, pop, 200, kernel="numpy"))
    effects = [parse_effect(s) for s in ("turn_shift:k=2", "stride_scale:a=1.3",
                                         "yaw_bias:delta=-0.7", "lateral_slip:gamma=0.05",
                                         "floor_slope:s=0.8,theta=200")]
    pop = _population(rng, 2000)
    _same(simulate(measured_table().rows, pop, 200, effects, kernel="numba"),
          simulate(measured_table().rows, pop, 200, effects, kernel="numpy"))


def test_auto_uses_numpy_where_the_kernel_does_not_apply():
    pop = _population(np.random.default_rng(2), 30)
    seq = [parse_effect("transition:alpha=0.3")]
    with pytest.raises(ValueError):
        simulate(measured_table().rows, pop, 100, seq, kernel="numba")
    with pytest.raises(ValueError):
        simulate(measured_table().rows, pop, 100, keep_paths=True, kernel="numba")
    kept = simulate(measured_table().rows, pop, 100, keep_paths=True)
    assert kept.poses is not None
    _same(kept, simulate(measured_table().rows, pop, 100, kernel="numba"))


@pytest.mark.parametrize("budget", [0, 5, 60, 200, 450])
def test_kernel_equals_numpy_on_batches_that_share_their_first_genes(budget):
    """A search's batch changes one gene and keeps those before it, its repetitions in order:
    the kernel starts each path where it parts from the one before. Whole neighbourhoods of
    each gene and paired repetition changes, on one and on many tables, with drift."""
    from pac_host.search.neighbours import neighbours, pair_neighbours

    rng = np.random.default_rng(budget + 7)
    models = measured_table().rows + rng.normal(0, 0.6, (5, 32, 3))
    drift = [parse_effect("floor_slope:s=0.8,theta=200")]
    for x in _population(rng, 28)[[0, 8, 16, 17, 18, 19]]:
        for j in range(9):
            batch = neighbours(x, 10**6, only=j)
            if not len(batch):
                continue
            batch = np.concatenate([x[None], batch, pair_neighbours(x, 10**6)])
            _same(simulate(shifted_table().rows, batch, budget, kernel="numba"),
                  simulate(shifted_table().rows, batch, budget, kernel="numpy"))
            _same(simulate(models, batch[:70], budget, drift, kernel="numba"),
                  simulate(models, batch[:70], budget, drift, kernel="numpy"))
