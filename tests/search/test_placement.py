"""Searching for a robot placed by hand: the stencil of start poses, scores pooled over its
walks (value for value those of separate walks), evaluations counted per walk, the options
and their bad input, and PAL ranking by the pooled scores."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import (
    START_POSE,
    Scorer,
    fitness_of_search_score,
    parse_turn_cycle,
    pooled_search_score,
    search_score,
    simulate,
)
from pac_host.coverage.placement import PlacementError, parse_placement, placed_fitness, summary
from pac_host.errors import InputError
from pac_host.learning import pal
from pac_host.model import measured_table, parse_effect, shifted_table
from pac_host.robot.evolve import EvolveConfig
from pac_host.search import anytime, cga
from pac_host.search.local import Exhausted, Objective
from pac_host.search.optimize import OptimizeConfig, optimize


def test_stencil_is_the_start_then_each_axis_two_sds_either_way():
    error = PlacementError(0.5, 1.0)
    poses = error.stencil((10.0, 20.0, 30.0))
    assert poses.shape == (7, 3)
    np.testing.assert_array_equal(poses[0], (10, 20, 30))
    moved = poses[1:] - poses[0]
    assert ((moved != 0).sum(axis=1) == 1).all()  # one coordinate each
    np.testing.assert_allclose(np.abs(moved).sum(axis=0), [4 * 0.5, 4 * 0.5, 4 * 1.0])
    np.testing.assert_allclose(moved.sum(axis=0), 0)  # down and up


def test_pooled_score_of_one_walk_is_the_search_score():
    rng = np.random.default_rng(0)
    f, r, v = rng.integers(0, 60, 50), rng.integers(0, 201, 50), rng.integers(0, 5000, 50)
    np.testing.assert_array_equal(pooled_search_score(f[None], r[None], v[None], 200),
                                  search_score(f, r, v, 200))


@pytest.mark.parametrize("effects", [(), ("transition:alpha=0.3",), ("battery_sag:beta=0.002",)])
def test_scorer_pools_the_walks_from_each_start_pose(effects):
    effects = tuple(parse_effect(e) for e in effects)
    rows = measured_table().rows
    pop = cga.random_population(np.random.default_rng(1), 40)
    pop[..., 1] //= 3
    poses = PlacementError(0.5, 1.0).stencil()
    pooled, scores = Scorer(rows, 200, effects, poses).both(pop)
    walks = [simulate(rows, pop, 200, effects, p) for p in poses]
    want = pooled_search_score(np.stack([w.fitness for w in walks]),
                               np.stack([w.reached_at for w in walks]),
                               np.stack([w.repeat_visits for w in walks]), 200)
    np.testing.assert_array_equal(pooled, want)
    np.testing.assert_array_equal(fitness_of_search_score(pooled, 200, starts=7),
                                  sum(w.fitness for w in walks))
    np.testing.assert_array_equal(scores, walks[0].score())  # the exact start's, as before
    # the walks differ: a stencil that were all one pose would not test the pooling
    assert len({tuple(w.fitness) for w in walks}) > 1


def test_a_turn_cycle_costs_one_evaluation_per_walk_and_the_limit_is_exact():
    rows = shifted_table().rows
    obj = Objective(rows, limit=7 * 10 + 3, placement=PlacementError(0.5, 1.0))
    pop = cga.random_population(np.random.default_rng(2), 25)
    keys = obj(pop)
    assert len(keys) == 10 and obj.evaluations == 70
    with pytest.raises(Exhausted):  # 3 evaluations left: not a whole turn cycle
        obj(pop)
    fits = [simulate(rows, pop[:10], 200, start_pose=p).fitness
            for p in PlacementError(0.5, 1.0).stencil()]
    best = int(np.argmax(keys))
    assert obj.fitness(int(keys[best])) == pytest.approx(np.mean([f[best] for f in fits]))


def test_objectives_with_other_placements_have_other_fingerprints():
    rows = shifted_table().rows
    prints = {Objective(rows).fingerprint(),
              Objective(rows, placement=PlacementError(0.5, 1.0)).fingerprint(),
              Objective(rows, placement=PlacementError(1.0, 1.0)).fingerprint()}
    assert len(prints) == 3


def test_placed_fitness_walks_drawn_start_poses():
    rows = shifted_table().rows
    genes = np.array([[12, 30], [3, 10]] + [[0, 0]] * 7)
    rng = np.random.default_rng(3)
    fit = placed_fitness(rows, genes, PlacementError(2.0, 5.0), 30, rng)
    poses = PlacementError(2.0, 5.0).draw(30, np.random.default_rng(3))
    want = [int(simulate(rows, genes, 200, start_pose=p).fitness[0]) for p in poses]
    np.testing.assert_array_equal(fit, want)
    s = summary(fit)
    assert s["walks"] == 30 and s["p10"] <= s["median"]


def test_optimize_with_placement_reports_the_drawn_walks_and_is_reproducible():
    rows = shifted_table().rows
    cfg = OptimizeConfig(evaluations=70_000, seed=4, placement=PlacementError(0.5, 1.0))
    a, b = optimize(rows, cfg), optimize(rows, cfg)
    assert a["turn_cycle"] == b["turn_cycle"] and a["placed"] == b["placed"]
    assert a["evaluations"] <= 70_000
    genes = np.array(a["genes"])
    walks = [simulate(rows, genes, 200, start_pose=p).fitness[0]
             for p in PlacementError(0.5, 1.0).stencil()]
    assert a["stencil_fitness"] == pytest.approx(np.mean(walks), abs=1e-3)
    assert a["fitness"] == walks[0]
    assert a["placed"]["walks"] == 200


def test_optimize_cli_placement_json(tmp_path):
    out = tmp_path / "o.json"
    res = CliRunner().invoke(main, ["optimize", "--evaluations", "20000", "--placement-error",
                                    "0.5,1", "--json", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["settings"]["placement"] == {"pos_cm": 0.5, "head_deg": 1.0}
    assert "10th percentile" in res.output


def test_simulate_cli_walks_a_turn_cycle_from_drawn_poses():
    tc = "29:7,21:13,18:2,7:21,21:1,13:5,20:7,23:8,2:10"  # sharp: 43 from the exact start
    args = ["simulate", "--table", "shifted", "--turn-cycle", tc, "--placement-error", "0.5,1",
            "--walks", "40", "--seed", "3", "--json"]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    expect = placed_fitness(shifted_table().rows, parse_turn_cycle(tc), PlacementError(0.5, 1.0),
                            40, np.random.default_rng(3))
    assert doc["fitness"] == 43
    assert doc["placed"] == {"placement": "0.5,1", "seed": 3, **summary(expect)}
    assert doc["placed"]["mean"] < 43  # the drawn poses lose what the exact start grazes
    text = CliRunner().invoke(main, args[:-1])
    assert text.exit_code == 0 and f"mean fitness {summary(expect)['mean']}" in text.output
    # without the option: the exact start alone, as before
    plain = json.loads(CliRunner().invoke(main, args[:5] + ["--json"]).output)
    assert "placed" not in plain and plain["fitness"] == 43


@pytest.mark.parametrize("text", ["abc", "1", "1,2,3", "-1,1", "1,nan", "100,1"])
def test_bad_placement_is_one_line_and_exit_2(text):
    with pytest.raises(InputError):
        parse_placement(text)
    for cmd in (["optimize", "--evaluations", "10"], ["simulate", "--turn-cycle", "1:1"]):
        res = CliRunner().invoke(main, [*cmd, "--placement-error", text])
        assert res.exit_code == 2, res.output
        assert len(res.output.strip().splitlines()) == 1 and "placement" in res.output


def test_placement_needs_an_anytime_search():
    with pytest.raises(InputError, match="anytime"):
        pal.PALConfig(search="cga", placement="0.5,1").check()
    pal.PALConfig(search="ils", search_evaluations=10, placement="0.5,1").check()
    assert parse_placement("0,0") is None and parse_placement("none") is None


def test_anytime_search_with_placement_ranks_by_the_pooled_score():
    rows = shifted_table().rows
    error = PlacementError(0.5, 1.0)
    pop = cga.random_population(np.random.default_rng(5), 16)
    scorer = Scorer(rows, 200, (), error.stencil())
    pop = pop[np.argsort(-scorer.both(pop)[0], kind="stable")]
    out, rec, _ = anytime.advance(rows, pop, 35_000, np.random.default_rng(6), placement=error)
    assert rec["evaluations"] <= 35_000 and rec["evaluations"] % 7 == 0
    pooled = scorer.both(out)[0]
    assert pooled[0] >= scorer.both(pop[:1])[0][0]
    # the front is the pooled best the search found, not the exact start's best
    cfg = pal.PALConfig(search="ils", search_evaluations=10, placement="0.5,1")
    rank, scores = pal._ranking(rows[None], out, cfg, ())
    np.testing.assert_array_equal(rank, pooled)
    np.testing.assert_array_equal(scores, cga.fitness(rows, out, 200))  # from the start
    exact, scores = pal._ranking(rows[None], out,
                                 pal.PALConfig(search="ils", search_evaluations=10), ())
    np.testing.assert_array_equal(exact, cga.fitness(rows, out, 200))
    np.testing.assert_array_equal(scores, exact)


def test_evolve_config_carries_the_placement():
    cfg = EvolveConfig(search="ils", search_evaluations=10, placement="0.5,1")
    assert cfg.pal().placement_error() == PlacementError(0.5, 1.0)
    assert START_POSE == tuple(PlacementError(0.5, 1.0).stencil()[0])
