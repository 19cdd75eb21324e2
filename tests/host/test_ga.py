"""The two GAs: reproducibility, operators, and partial recombination's defining property."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.coverage import parse_turn_cycle, simulate
from pac_host.learning import model_ga
from pac_host.model import measured_table, shifted_table
from pac_host.search import cga
from pac_host.search.ga_ops import tournament, two_point_crossover

M = measured_table().rows
A = shifted_table().rows


def test_cga_same_seed_same_run_different_seed_different_run():
    def run(seed):
        rng = np.random.default_rng(seed)
        pop = cga.random_population(rng, 32)
        return cga.evolve(M, pop, 15, rng, cga.CGAConfig(population=32))

    (p1, b1), (p2, b2), (p3, _) = run(11), run(11), run(12)
    assert np.array_equal(p1, p2) and np.array_equal(b1, b2)
    assert not np.array_equal(p1, p3)


def test_cga_improves_and_elitism_never_loses_the_best():
    rng = np.random.default_rng(0)
    pop = cga.random_population(rng, 64)
    start = cga.fitness(M, pop).max()
    pop, best = cga.evolve(M, pop, 60, rng, cga.CGAConfig(population=64))
    assert np.all(np.diff(best) >= 0)
    assert best[-1] > start
    assert cga.fitness(M, pop[:1])[0] == best[-1]  # returned sorted, best first


def test_cga_mutation_flips_bits_at_the_rate_and_stays_in_range():
    rng = np.random.default_rng(1)
    pop = cga.random_population(rng, 2000)
    out = cga.mutate(pop, 0.05, rng)
    flips = sum(bin(int(v)).count("1") for v in (pop ^ out).ravel())
    expected = 0.05 * 2000 * 9 * 11
    assert abs(flips - expected) < 4 * np.sqrt(expected)
    assert out[..., 0].max() <= 31 and out[..., 1].max() <= 63 and out.min() >= 0


def test_crossover_moves_whole_genes():
    rng = np.random.default_rng(2)
    a = np.zeros((500, 9, 2), dtype=int)
    b = np.ones((500, 9, 2), dtype=int)
    child = two_point_crossover(a, b, 1.0, rng)
    assert np.all(child[..., 0] == child[..., 1])  # a gene's two fields travel together
    runs = np.abs(np.diff(child[..., 0], axis=1)).sum(axis=1)
    assert runs.max() <= 2 and child.sum() > 0
    assert np.array_equal(two_point_crossover(a, b, 0.0, rng), a)


def test_tournament_prefers_the_fitter():
    rng = np.random.default_rng(3)
    fit = np.arange(10.0)
    wins = np.bincount(tournament(fit, 20000, rng, 2), minlength=10)
    assert wins[9] > wins[5] > wins[0]


def test_used_gait_ids_in_order_of_first_use():
    tests = np.stack([parse_turn_cycle("12:14,3:10,12:3,19:10"),
                      parse_turn_cycle("3:1,7:0,25:2"),
                      parse_turn_cycle("19:5,30:4")])
    assert model_ga.used_gait_ids(tests).tolist() == [12, 3, 19, 25, 30]


def test_model_fitness_is_the_six_absolute_differences():
    rng = np.random.default_rng(5)
    tables = model_ga.perturbed_population(M, 4, rng)
    tests = cga.random_population(rng, 3)
    observed = np.array([[5, 2], [7, 7], [0, 0]])
    got = model_ga.model_fitness(tables, tests, observed)
    for m in range(4):
        cov = simulate(tables[m], tests)
        want = sum(abs(int(cov.blocks_covered[k]) - observed[k, 0])
                   + abs(int(cov.blocks_covered_once[k]) - observed[k, 1]) for k in range(3))
        assert got[m] == want


def _gap_setup(seed=6):
    rng = np.random.default_rng(seed)
    pop = cga.random_population(rng, 64)
    pop, _ = cga.evolve(M, pop, 30, rng, cga.CGAConfig(population=64))
    tests = pop[:3]
    cov = simulate(A, tests)
    observed = np.stack([cov.blocks_covered, cov.blocks_covered_once], axis=1)
    models = model_ga.perturbed_population(M, 64, rng)
    return rng, tests, observed, models


def _multiset(rows):
    return sorted(map(tuple, rows.reshape(-1, 3).tolist()))


def test_partial_recombination_leaves_unused_genes_bit_for_bit():
    rng, tests, observed, models = _gap_setup()
    used = model_ga.used_gait_ids(tests)
    unused = np.setdiff1d(np.arange(32), used)
    assert 0 < len(used) < 32
    new, _ = model_ga.evolve(models, tests, observed, 20, rng, "partial")
    # Each model's unused genes are exactly some model's unused genes before.
    before = {tuple(models[m, unused].ravel()) for m in range(len(models))}
    assert all(tuple(new[m, unused].ravel()) in before for m in range(len(new)))
    # ... while the used genes did evolve.
    assert not np.array_equal(np.sort(new[:, used], axis=0), np.sort(models[:, used], axis=0))


def test_full_recombination_changes_unused_genes():
    rng, tests, observed, models = _gap_setup()
    unused = np.setdiff1d(np.arange(32), model_ga.used_gait_ids(tests))
    new, _ = model_ga.evolve(models, tests, observed, 20, rng, "full")
    before = {tuple(models[m, unused].ravel()) for m in range(len(models))}
    changed = sum(tuple(new[m, unused].ravel()) not in before for m in range(len(new)))
    assert changed > len(new) // 2
    assert _multiset(new[:, unused]) != _multiset(models[:, unused])


@pytest.mark.parametrize("method", ["full", "partial"])
def test_model_ga_reduces_disagreement_with_the_robot(method):
    rng, tests, observed, models = _gap_setup(7)  # no perturbed model agrees at the start
    start = model_ga.model_fitness(models, tests, observed).min()
    new, err = model_ga.evolve(models, tests, observed, 40, rng, method)
    assert start > 0 and err[0] < start
    assert np.all(np.diff(err) >= 0)
    assert err[0] == model_ga.model_fitness(new[:1], tests, observed)[0]


def test_model_ga_rejects_unknown_method():
    rng, tests, observed, models = _gap_setup()
    with pytest.raises(ValueError, match="unknown recombination"):
        model_ga.evolve(models, tests, observed, 1, rng, "half")


def test_step_error_is_zero_for_the_robot_itself_and_positive_otherwise():
    rng = np.random.default_rng(12)
    tests = cga.random_population(rng, 3)
    cov = simulate(A, tests, 120, keep_paths=True)
    err = model_ga.step_error(tests, list(cov.poses), 120)
    got = err(np.stack([A, M]))
    assert got[0] == pytest.approx(0.0, abs=1e-9)
    assert got[1] > 0.1


def test_step_error_only_sees_the_rows_the_tests_use():
    rng = np.random.default_rng(13)
    tests = cga.random_population(rng, 3)
    tests[:, 3:, 1] = 0  # three genes each
    cov = simulate(A, tests, 80, keep_paths=True)
    err = model_ga.step_error(tests, list(cov.poses), 80)
    unused = np.setdiff1d(np.arange(32), model_ga.used_gait_ids(tests, 80))
    other = A.copy()
    other[unused] += 5.0
    assert err(other[None])[0] == pytest.approx(0.0, abs=1e-9)


def test_partial_recombination_with_step_error_converges_on_the_used_rows():
    rng = np.random.default_rng(14)
    tests = cga.random_population(rng, 3)
    cov = simulate(A, tests, keep_paths=True)
    err = model_ga.step_error(tests, list(cov.poses))
    models = model_ga.perturbed_population(M, 64, rng)
    used = model_ga.used_gait_ids(tests)
    before = np.abs(models[0, used] - A[used]).mean()
    new, errors = model_ga.evolve(models, tests, None, 60, rng, "partial", error_fn=err)
    assert errors[0] < err(models).min()
    assert np.abs(new[0, used] - A[used]).mean() < 0.65 * before
