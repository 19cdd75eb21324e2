"""The coverage simulator: the detection rule, the figures, and the vectorized batch paths."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.coverage import (
    START_POSE,
    coverage_of_poses,
    detect_blocks,
    expand,
    figures_from_blocks,
    fitness_of_search_score,
    format_turn_cycle,
    parse_turn_cycle,
    search_score,
    simulate,
)
from pac_host.errors import InputError
from pac_host.model import Effect, measured_table, rollout, shifted_table
from pac_host.search import cga

M = measured_table().rows


@pytest.mark.parametrize("pose, block", [
    ((30, 30, 0), 0),          # body across x, well inside block (row 0, col 0)
    ((150, 90, 45), 5),        # diagonal body inside row 1, col 2
    ((57, 30, 0), -1),         # heading +y: body spans x 51..63, straddles columns 0 and 1
    ((45, 58, 90), -1),        # heading +x: body spans y 52..64, straddles rows 0 and 1
    ((45, 54, 90), -1),        # y 48..60: the far end lies on row 1's border, so in row 1
    ((45, 6, 90), 0),          # y 0..12: the near end on y = 0 is inside
    ((45, 5.99, 90), -1),
    ((45, 53.9, 90), 0),
    ((-1, 30, 0), -1),         # outside the area on the left
    ((178, 30, 0), -1),        # x 172..184 passes the right edge at 180
    ((30, -2, 90), -1),        # below y = 0
    ((100, 1000, 180), 49),    # far up: row 16 (960..1020), col 1
])
def test_detection_rule_by_hand(pose, block):
    assert detect_blocks(np.array([pose], dtype=float))[0] == block


def test_figures_by_hand():
    # visits: block 0 twice, block 1 twice (left then re-entered), block 2 once; the row is
    # full, and so the fitness reached, when block 2 is first detected (pose 5)
    c, once, fit, rep, at = figures_from_blocks(np.array([[0, 0, 1, -1, 1, 2, 0]]))
    assert (c[0], once[0], fit[0], rep[0], at[0]) == (3, 1, 3, 2, 5)
    # row 0 full, row 1 has two blocks: 3 * 1 + 2, reached at the second of them
    assert [f[0] for f in figures_from_blocks(np.array([[0, 1, 2, 3, 5]]))[2:]] == [5, 0, 4]
    # a mine left behind in row 0 caps the score even though row 1 is full: the fitness (2)
    # counts blocks 1 and 2, reached at pose 1, whatever the path covers after
    c, once, fit, rep, at = figures_from_blocks(np.array([[1, 2, 3, 4, 5]]))
    assert (c[0], fit[0], at[0]) == (5, 2, 1)
    # blocks first detected out of order: the last counted one decides
    assert figures_from_blocks(np.array([[-1, 2, 0, 0, 4, 1, 2]]))[4][0] == 5
    # nothing detected
    assert [f[0] for f in figures_from_blocks(np.array([[-1, -1]]))] == [0, 0, 0, 0, 0]


def test_search_score_ranks_fitness_then_reaching_it_sooner_then_fewer_repeats():
    fitness = np.array([5, 5, 5, 6, 0])
    reached = np.array([120, 80, 80, 199, 0])
    repeats = np.array([0, 3, 1, 9, 0])
    s = search_score(fitness, reached, repeats, 200)
    assert np.argsort(-s).tolist() == [3, 2, 1, 0, 4]
    np.testing.assert_array_equal(fitness_of_search_score(s, 200), fitness)
    # the paths' figures: the same order as the coverage score wherever fitness differs
    rows = measured_table().rows
    pop = cga.random_population(np.random.default_rng(4), 400)
    cov = simulate(rows, pop)
    key = search_score(cov.fitness, cov.reached_at, cov.repeat_visits, 200)
    np.testing.assert_array_equal(fitness_of_search_score(key, 200), cov.fitness)
    assert ((cov.reached_at >= 0) & (cov.reached_at <= 200)).all()
    # the start pose is in block 0: a fitness of 1 is reached there, more takes gait cycles
    assert (cov.reached_at[cov.fitness >= 2] > 0).all() and (cov.fitness >= 2).any()


def test_expand_loops_and_skips_zero_repetitions():
    genes = parse_turn_cycle("12:2,5:0,3:1")
    ids, still = expand(genes[None], 7)
    assert ids[0].tolist() == [12, 12, 3, 12, 12, 3, 12]
    assert not still[0]
    ids, still = expand(np.zeros((1, 9, 2), dtype=int), 5)
    assert still[0]


@pytest.mark.parametrize("budget", [0, 1, 200, 1100])  # looked up, and computed past 1024
def test_expand_matches_the_loop_written_out(budget):
    rng = np.random.default_rng(6)
    genes = _random_genes(rng, 40)
    genes[:20, :, 1] %= 4  # short loops, wrapping many times
    genes[3, :, 1] = 0
    ids, still = expand(genes, budget)
    for g, row, s in zip(genes, ids, still, strict=True):
        loop = [int(i) for i, r in g for _ in range(r)]
        assert s == (not loop)
        want = [loop[t % len(loop)] for t in range(budget)] if loop else [0] * budget
        assert row.tolist() == want


def test_simulated_path_is_the_model_rollout():
    genes = parse_turn_cycle("12:14,3:10,12:3,19:10")
    cov = simulate(M, genes, 120, keep_paths=True)
    ids, _ = expand(genes[None], 120)
    np.testing.assert_allclose(cov.poses[0], rollout(M, (45, 30, 90), ids[0]), atol=1e-9)
    again = coverage_of_poses(cov.poses[0])
    assert again.row() == cov.row(0)


def test_standing_still_turn_cycle():
    cov = simulate(M, np.zeros((9, 2), dtype=int), 50, keep_paths=True)
    assert np.all(cov.poses[0] == [45, 30, 90])
    assert cov.row(0) == {"blocks_covered": 1, "blocks_covered_once": 1, "fitness": 1,
                          "repeat_visits": 0}


def _random_genes(rng, n):
    return np.stack([rng.integers(0, 32, (n, 9)), rng.integers(0, 64, (n, 9))], -1)


@pytest.mark.parametrize("effects", [(), (Effect("transition", {"alpha": 0.3}),),
                                     (Effect("floor_slope", {"s": 1.0, "theta": 45}),)])
def test_population_batch_equals_one_at_a_time(effects):
    rng = np.random.default_rng(3)
    genes = _random_genes(rng, 300)  # spans several inner chunks
    genes[7, :, 1] = 0
    batch = simulate(M, genes, 200, effects)
    for i in range(0, 300, 23):
        one = simulate(M, genes[i], 200, effects)
        assert one.row(0) == batch.row(i)


def test_model_population_batch_equals_one_table_at_a_time():
    rng = np.random.default_rng(4)
    tables = M[None] + rng.normal(size=(5, 32, 3))
    genes = _random_genes(rng, 3)
    batch = simulate(tables, genes)
    assert batch.fitness.shape == (5, 3)
    for m in range(5):
        one = simulate(tables[m], genes)
        assert np.array_equal(one.score(), batch.score()[m])


@pytest.mark.parametrize("effects", [(), (Effect("transition", {"alpha": 0.3}),),
                                     (Effect("floor_slope", {"s": 1.0, "theta": 45}),),
                                     (Effect("turn_shift", {"k": 1}),)])
def test_kept_paths_are_the_rollouts_across_tables_and_chunks(effects):
    # the batch's per-gene move lookup must walk each path exactly as the one-path rollout
    # (the pose update's reference), including standing still and on tables past the first
    rng = np.random.default_rng(5)
    tables = M[None] + rng.normal(size=(3, 32, 3)) * 0.5
    genes = _random_genes(rng, 100)
    genes[4, :, 1] = 0  # stands still
    genes[9, :, 1] = 0
    genes[9, 2, 1] = 1  # a loop of one gait cycle
    cov = simulate(tables, genes, 60, effects, keep_paths=True)  # 300 paths: several chunks
    ids, still = expand(genes, 60)
    assert still.tolist() == [i == 4 for i in range(100)]
    assert np.all(cov.poses[:, 4] == START_POSE)
    for m, i in [(0, 0), (0, 9), (1, 50), (2, 9), (2, 99)]:
        want = rollout(tables[m], START_POSE, ids[i], effects)
        np.testing.assert_allclose(cov.poses[m, i], want, atol=1e-9)
        assert coverage_of_poses(want).row() == cov.row((m, i))


def test_gap_between_model_and_actual_is_visible():
    genes = parse_turn_cycle("12:14,3:10,12:3,19:10")
    a = simulate(M, genes, keep_paths=True)
    b = simulate(shifted_table().rows, genes, keep_paths=True)
    assert not np.allclose(a.poses[0, -1], b.poses[0, -1])


@pytest.mark.parametrize("text, message", [
    ("12:14,32:1", "gait cycle id 32 outside 0..31"),
    ("12:64", "repetitions 64 outside 0..63"),
    ("12:-1", "repetitions -1 outside"),
    ("12", "expected 'id:reps'"),
    ("", "empty"),
    (",".join(["1:1"] * 10), "at most 9"),
])
def test_turn_cycle_errors(text, message):
    with pytest.raises(InputError, match=message):
        parse_turn_cycle(text)


def test_turn_cycle_round_trip():
    assert format_turn_cycle(parse_turn_cycle("12:14, 3:10,19:0")) == "12:14,3:10"


def test_negative_budget_rejected():
    with pytest.raises(InputError, match="budget"):
        simulate(M, parse_turn_cycle("12:1"), -5)
