"""Searching over the model's posterior: each turn cycle walked on the model and on tables drawn
from its posterior, the scores pooled (value for value those of separate walks), evaluations
counted per walk, the setting's bad input, and PAL ranking and searching by the pooled score."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import (
    Scorer,
    fitness_of_search_score,
    parse_turn_cycle,
    pooled_search_score,
    simulate,
)
from pac_host.coverage.placement import PlacementError
from pac_host.errors import InputError
from pac_host.experiments.experiment import ExperimentConfig, run_experiment
from pac_host.learning import pal, test_selection
from pac_host.model import measured_table, parse_effect, shifted_table
from pac_host.robot.evolve import EvolveConfig
from pac_host.search import anytime, cga
from pac_host.search.local import Objective


def _draws(rows: np.ndarray, k: int, sd: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rows + rng.normal(0, sd, size=(k, *rows.shape))


@pytest.mark.parametrize("effects", [(), ("transition:alpha=0.3",), ("battery_sag:beta=0.002",)])
def test_scorer_pools_the_walks_on_each_table(effects):
    effects = tuple(parse_effect(e) for e in effects)
    rows = measured_table().rows
    models = _draws(rows, 2, 1.0, 0)
    pop = cga.random_population(np.random.default_rng(1), 40)
    pop[..., 1] //= 3
    scorer = Scorer(rows, 200, effects, models=models)
    assert scorer.walks == 3
    pooled, scores = scorer.both(pop)
    walks = [simulate(t, pop, 200, effects) for t in (rows, *models)]
    want = pooled_search_score(np.stack([w.fitness for w in walks]),
                               np.stack([w.reached_at for w in walks]),
                               np.stack([w.repeat_visits for w in walks]), 200)
    np.testing.assert_array_equal(pooled, want)
    np.testing.assert_array_equal(scores, walks[0].score())  # the model's own, as before
    assert len({tuple(w.fitness) for w in walks}) > 1  # the tables differ


def test_tables_and_start_poses_pool_together():
    rows = shifted_table().rows
    models = _draws(rows, 1, 0.5, 2)
    poses = PlacementError(0.5, 1.0).stencil()
    pop = cga.random_population(np.random.default_rng(3), 12)
    scorer = Scorer(rows, 200, (), poses, models)
    assert scorer.walks == 14
    fit = sum(simulate(t, pop, 200, start_pose=p).fitness for t in (rows, *models) for p in poses)
    np.testing.assert_array_equal(fitness_of_search_score(scorer.both(pop)[0], 200, starts=14),
                                  fit)


def test_identical_tables_leave_the_ranking_and_the_mean_fitness_alone():
    rows = shifted_table().rows
    pop = cga.random_population(np.random.default_rng(4), 30)
    one, pooled = Objective(rows), Objective(rows, models=np.stack([rows, rows]))
    a, b = one(pop), pooled(pop)
    np.testing.assert_array_equal(np.argsort(-a, kind="stable"), np.argsort(-b, kind="stable"))
    assert pooled.evaluations == 3 * one.evaluations == 90
    assert [pooled.fitness(int(s)) for s in b] == [one.fitness(int(s)) for s in a]


def test_a_turn_cycle_on_rows_the_tables_disagree_on_scores_lower():
    rows = shifted_table().rows
    best = parse_turn_cycle("29:7,21:11,17:3,7:21,3:1,21:13,12:4,7:1,2:8")  # a sweep of 46
    other = parse_turn_cycle("12:60,3:10")  # uses neither 29 nor 17
    alt = rows.copy()
    alt[[29, 17], 2] += 6.0  # the other table turns more on two of the sweep's rows
    obj = Objective(rows, models=alt[None])
    on_model = simulate(rows, np.stack([best, other])).fitness
    pooled = [obj.fitness(int(s)) for s in obj(np.stack([best, other]))]
    assert on_model[0] == 46 and pooled[0] < 46  # the sweep breaks on the other table
    assert pooled[1] == on_model[1]  # a turn cycle off those rows is as sure as before


def test_other_tables_give_other_fingerprints():
    rows = shifted_table().rows
    prints = {Objective(rows).fingerprint(),
              Objective(rows, models=_draws(rows, 1, 1.0, 0)).fingerprint(),
              Objective(rows, models=_draws(rows, 1, 1.0, 1)).fingerprint()}
    assert len(prints) == 3


def test_search_models_is_checked():
    ok = pal.PALConfig(search="ils", search_evaluations=10, search_models=4)
    ok.check()
    for bad, match in ((pal.PALConfig(search_models=4), "anytime"),
                       (pal.PALConfig(search="ils", search_evaluations=10, search_models=0),
                        "search-models"),
                       (pal.PALConfig(search="ils", search_evaluations=10, search_models=65,
                                      model_population=64), "search-models")):
        with pytest.raises(InputError, match=match):
            bad.check()


def test_anytime_pal_ranks_and_searches_by_the_score_pooled_over_the_models():
    rows = shifted_table().rows
    models = np.concatenate([rows[None], _draws(rows, 5, 1.0, 7)])
    cfg = pal.PALConfig(search="ils", search_evaluations=10, search_models=3)
    pop = cga.random_population(np.random.default_rng(5), 16)
    scorer = Scorer(rows, 200, (), models=models[1:3])
    rank, scores = pal._ranking(models, pop, cfg, ())
    np.testing.assert_array_equal(rank, scorer.both(pop)[0])
    np.testing.assert_array_equal(scores, cga.fitness(rows, pop, 200))
    pop = pop[np.argsort(-rank, kind="stable")]
    out, rec, _ = anytime.advance(rows, pop, 30_000, np.random.default_rng(6),
                                  models=models[1:3])
    assert rec["evaluations"] <= 30_000 and rec["evaluations"] % 3 == 0
    assert scorer.both(out[:1])[0][0] >= scorer.both(pop[:1])[0][0]


@pytest.mark.parametrize("args", [["--search-models", "0"], ["--search-models", "x"],
                                  ["--search-models", "4", "--profile", "paper"],
                                  ["--search-models", "65"]])
def test_bad_search_models_is_one_line_and_exit_2(tmp_path, args):
    res = CliRunner().invoke(main, ["experiment", "--seeds", "1", "--generations", "40",
                                    "--out", str(tmp_path / "x"), *args])
    assert res.exit_code == 2, res.output
    assert len(res.output.strip().splitlines()) == 1 and "search-models" in res.output
    assert not (tmp_path / "x" / "log.jsonl").exists()


def test_evolve_config_and_the_oracle_carry_the_setting(tmp_path):
    cfg = EvolveConfig(search="ils", search_evaluations=10, correction="fit", search_models=3)
    assert cfg.pal().search_models == 3
    cfg.check()
    # the experiment's oracle walks the robot's own table: one model, nothing to pool
    ecfg = ExperimentConfig(seeds=1, generations=80, methods=("partial", "oracle"),
                            initial_generations=5, optimum_runs=1, optimum_evaluations=2_000,
                            pal=pal.PALConfig(search="ils", search_evaluations=3_001,
                                              search_models=3, cga_population=16,
                                              model_population=8))
    s = run_experiment(tmp_path, ecfg, measured_table(), shifted_table(), jobs=1)
    assert {r["method"] for r in s["runs"]} == {"partial", "oracle"}
    recs = [json.loads(line) for line in (tmp_path / "log.jsonl").read_text().splitlines()]
    spent = {m: [r["search"]["evaluations"] for r in recs if r["method"] == m]
             for m in ("partial", "oracle")}
    assert spent["partial"] and all(e % 3 == 0 and e <= 3_001 for e in spent["partial"])
    assert set(spent["oracle"]) == {3_001}  # one walk a turn cycle


def test_the_model_alone_best_comes_second_and_is_the_best_on_the_model_scored():
    rows = shifted_table().rows
    models = _draws(rows, 3, 1.0, 8)
    pop = cga.random_population(np.random.default_rng(9), 16)
    out, rec, _ = anytime.advance(rows, pop, 24_000, np.random.default_rng(10), models=models)
    alone = cga.fitness(rows, out[:2], 200)
    assert alone[1] == rec["best_alone_score"] >= alone[0]
    assert (alone[1] >= cga.fitness(rows, pop, 200)).all()  # the start was scored too
    pooled = Scorer(rows, 200, (), models=models).both(out[:2])[0]
    assert pooled[0] >= pooled[1]  # the front is the pooled best
    _, rec1, _ = anytime.advance(rows, pop, 24_000, np.random.default_rng(10))
    assert "best_alone_score" not in rec1


def test_a_hopeful_turn_cycle_takes_the_first_test_after_the_best():
    rng = np.random.default_rng(11)
    rows = measured_table().rows
    models = np.concatenate([rows[None], _draws(rows, 7, 1.0, 12)])
    pop = cga.random_population(rng, 24)
    best, hopeful = pop[0], pop[5]
    pert = pal.perturbations(best, rng, pal.PALConfig())
    row_var = models.var(axis=0).sum(axis=-1)
    plain = test_selection.choose(best, pert, pop, models, row_var, 200)
    tests = test_selection.choose(best, pert, pop, models, row_var, 200, hopeful=hopeful)
    assert tests.shape == (3, 9, 2)
    np.testing.assert_array_equal(tests[0], best)
    np.testing.assert_array_equal(tests[1], hopeful)
    assert tests[2].tobytes() not in (best.tobytes(), hopeful.tobytes())
    np.testing.assert_array_equal(tests[2], plain[1] if plain[1].tobytes() != hopeful.tobytes()
                                  else plain[2])
    same = test_selection.choose(best, pert, pop, models, row_var, 200, hopeful=best)
    np.testing.assert_array_equal(same, plain)  # the best is already tested
