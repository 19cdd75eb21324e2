"""Searching for what a robot with step noise delivers: the compiled noisy kernel (value for
value the noise-free simulator at zero noise, the numpy reference's figures with noise),
common random numbers, the noisy objective, ``optimize --step-noise`` (reproducible, the fresh
walks in its JSON) and its bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import parse_turn_cycle, simulate
from pac_host.coverage.noisy import (
    NoisyScorer,
    NoisyWalks,
    draw_normals,
    fitness_of_noisy_score,
    noisy_search_score,
    reference_figures,
)
from pac_host.coverage.placement import PlacementError
from pac_host.errors import InputError
from pac_host.model import measured_table, parse_effect, shifted_table
from pac_host.model.step_noise import NONE, StepNoise, parse_step_noise
from pac_host.search import cga
from pac_host.search.local import Objective
from pac_host.search.optimize import FRESH_WALKS, OptimizeConfig, optimize

NOISE = parse_step_noise("0.3,1")


def _population(seed: int, n: int) -> np.ndarray:
    pop = cga.random_population(np.random.default_rng(seed), n)
    pop[::2, :, 1] //= 4  # short loops the budget repeats, as well as long ones
    return pop


@pytest.mark.parametrize("effects", [(), ("turn_scale:c=0.9", "floor_slope:s=0.3,theta=40")])
@pytest.mark.parametrize("table", [measured_table, shifted_table])
def test_zero_noise_gives_the_simulator_figures_value_for_value(table, effects):
    effects = tuple(parse_effect(e) for e in effects)
    rows = table().rows
    pop = _population(0, 60)
    pop[3, :, 1] = 0  # stands still
    z = draw_normals(np.random.default_rng(1), 5, 200)
    fig = NoisyWalks(rows, NONE, z, 200, effects).figures(pop)
    cov = simulate(rows, pop, 200, effects, kernel="numpy")
    want = np.stack([cov.blocks_covered, cov.blocks_covered_once, cov.fitness,
                     cov.repeat_visits, cov.reached_at])
    assert fig.shape == (5, 60, 5)
    np.testing.assert_array_equal(fig, np.repeat(want[..., None], 5, axis=2))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kernel_agrees_with_the_numpy_reference(seed):
    rng = np.random.default_rng(seed)
    rows = (shifted_table().rows if seed % 2 else
            measured_table().rows + rng.normal(size=(32, 3)) * 0.5)
    # uniform noise (the rotation tabulated), and per gait id with many deviations in dH
    # (computed per step)
    noises = [NOISE, StepNoise(rng.uniform(0, 1.5, (32, 3)))]
    pop = _population(seed, 30)
    z = draw_normals(rng, 12, 200)
    starts = PlacementError(0.5, 1.0).draw(12, rng)
    for noise in noises:
        fig = NoisyWalks(rows, noise, z, 200, (), starts).figures(pop)
        ref = reference_figures(rows, pop, noise, z, 200, (), starts)
        np.testing.assert_array_equal(fig[2], ref[2])  # fitness
        # the rest too, barring a pose a rounding error from a border
        assert (fig == ref).mean() > 0.999
        assert fig[2].std() > 0  # the walks differ


def test_sequence_effects_walk_by_the_reference():
    effects = (parse_effect("transition:alpha=0.3"),)
    pop = _population(3, 6)
    z = draw_normals(np.random.default_rng(3), 4, 100)
    walks = NoisyWalks(shifted_table().rows, NOISE, z, 100, effects)
    assert not walks.compiled
    np.testing.assert_array_equal(
        walks.figures(pop), reference_figures(shifted_table().rows, pop, NOISE, z, 100, effects))


def test_common_random_numbers_same_normals_same_scores_in_any_order():
    rows = shifted_table().rows
    pop = _population(4, 40)
    z = draw_normals(np.random.default_rng(7), 16, 200)
    fig = NoisyWalks(rows, NOISE, z).figures(pop)
    again = NoisyWalks(rows, NOISE, z.copy()).figures(pop)
    np.testing.assert_array_equal(fig, again)
    order = np.random.default_rng(0).permutation(len(pop))
    shuffled = NoisyWalks(rows, NOISE, z).figures(pop[order])
    np.testing.assert_array_equal(shuffled, fig[:, order])  # each scored alone as in the batch
    one = np.stack([NoisyWalks(rows, NOISE, z).figures(g[None])[:, 0] for g in pop[:5]], 1)
    np.testing.assert_array_equal(one, fig[:, :5])
    other = NoisyWalks(rows, NOISE, draw_normals(np.random.default_rng(8), 16, 200))
    assert not np.array_equal(other.figures(pop)[2], fig[2])


def test_noisy_scores_rank_the_mean_then_reached_sooner_or_a_quantile():
    f = np.array([[10, 10, 10, 10], [4, 20, 20, 20], [10, 10, 10, 10]])
    r = np.array([[50] * 4, [50] * 4, [40] * 4])
    mean = noisy_search_score(f, r, 200)
    assert mean[1] > mean[2] > mean[0]
    np.testing.assert_allclose(fitness_of_noisy_score(mean, 200, 4), [10, 16, 10])
    low = noisy_search_score(f, r, 200, quantile=0.25)
    assert low[0] > low[1]  # the bad day counts
    assert low[0] == low[2]  # then the mean, not the pace
    np.testing.assert_allclose(fitness_of_noisy_score(low, 200, 4, 0.25), [10, 4, 10])


def test_objective_with_step_noise_scores_the_mean_of_its_walks_and_counts_each_walk():
    rows = shifted_table().rows
    z = draw_normals(np.random.default_rng(0), 20, 200)
    pop = _population(5, 10)
    objective = Objective(rows, step_noise=NOISE, normals=z, keep_finalists=3)
    keys = objective(pop)
    assert objective.evaluations == 10 * 20
    fit = NoisyScorer(rows, NOISE, z).both(pop)[0]
    np.testing.assert_array_equal(keys, fit)
    mean = NoisyWalks(rows, NOISE, z).figures(pop)[2].mean(axis=1)
    i = int(np.argmax(keys))
    assert objective.fitness(objective.best_search_score) == pytest.approx(mean[i])
    assert [k for k, _ in objective.finalists] == [int(keys[i])]
    bests = [int(keys[i])]
    for seed in range(6, 12):  # each batch's best is offered; the best three distinct kept
        bests.append(int(objective(_population(seed, 10)).max()))
    kept = [k for k, _ in objective.finalists]
    assert kept == sorted(set(bests), reverse=True)[:3]
    for k, g in objective.finalists:
        assert NoisyScorer(rows, NOISE, z).both(g[None])[0][0] == k
    plain = Objective(rows)
    assert plain.fingerprint() != objective.fingerprint()


def test_a_remembered_batch_is_charged_in_full_and_scored_once_per_model(monkeypatch):
    # every chain of a punctuation scores the model's re-expressed library: the second is
    # charged the same evaluations and finds the same best, without walking it again
    rows = shifted_table().rows
    z = draw_normals(np.random.default_rng(1), 16, 200)
    pop = _population(7, 12)
    first = Objective(rows, step_noise=NOISE, normals=z)
    keys = first(pop, remember=True)
    walked = []
    real = NoisyScorer.both
    monkeypatch.setattr(NoisyScorer, "both", lambda self, g: walked.append(len(g)) or real(self, g))
    again = Objective(rows, step_noise=NOISE, normals=z, limit=10 * 16)
    np.testing.assert_array_equal(again(pop, remember=True), keys[:10])  # cut at its limit
    assert walked == [10] and again.evaluations == 10 * 16  # a cut batch is another batch
    same = Objective(rows, step_noise=NOISE, normals=z)
    np.testing.assert_array_equal(same(pop, remember=True), keys)
    assert walked == [10] and same.evaluations == first.evaluations == 12 * 16
    assert np.array_equal(same.best, first.best) and same.best_score == first.best_score
    other = Objective(rows, step_noise=NOISE, normals=z * 1.5)  # other walks: scored anew
    other(pop, remember=True)
    bent = rows.copy()
    bent[3, 0] += 1e-9  # another model, however close
    Objective(bent, step_noise=NOISE, normals=z)(pop, remember=True)
    assert walked == [10, 12, 12]


def test_optimize_with_step_noise_is_reproducible_and_measures_on_fresh_walks():
    rows = shifted_table().rows
    cfg = OptimizeConfig(evaluations=60_000, seed=2, step_noise=NOISE, walks=16, chains=2)
    a, b = optimize(rows, cfg), optimize(rows, cfg)
    assert a["turn_cycle"] == b["turn_cycle"] and a["fresh"] == b["fresh"]
    assert a["evaluations"] <= 60_000
    fresh = a["fresh"]
    assert fresh["walks"] == FRESH_WALKS
    lo, hi = fresh["ci95"]
    assert lo < fresh["mean"] < hi
    genes = np.array(a["genes"])
    assert a["fitness"] == simulate(rows, genes).fitness[0]  # the noise-free figures
    assert a["walks"] == 16 and a["finalists"]["turn_cycles"] >= 1
    other = optimize(rows, OptimizeConfig(evaluations=60_000, seed=3, step_noise=NOISE,
                                          walks=16, chains=2))
    assert other["fresh"] != a["fresh"]


def test_optimize_cli_step_noise_json(tmp_path):
    out = tmp_path / "o.json"
    args = ["optimize", "--evaluations", "30000", "--step-noise", "0.3,1", "--walks", "16",
            "--quantile", "0.2", "--placement-error", "0.5,1", "--json", str(out)]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["settings"]["step_noise"] == {"F": 0.3, "T": 0.3, "dH": 1.0}
    assert doc["walks"] == 16 and doc["quantile"] == 0.2
    assert doc["fresh"]["walks"] == FRESH_WALKS and len(doc["fresh"]["ci95"]) == 2
    assert "quantile_fitness" in doc["fresh"] and "placed" not in doc
    assert "fresh noisy walks (95% interval" in res.output
    again = CliRunner().invoke(main, args[:-2] + ["--json", str(tmp_path / "b.json")])
    assert json.loads((tmp_path / "b.json").read_text())["fresh"] == doc["fresh"], again.output


def test_optimize_cli_without_step_noise_is_unchanged(tmp_path):
    args = ["optimize", "--evaluations", "20000", "--seed", "1", "--json"]
    a = CliRunner().invoke(main, [*args, str(tmp_path / "a.json")])
    b = CliRunner().invoke(main, [*args, str(tmp_path / "b.json"), "--step-noise", "none"])
    assert a.exit_code == 0 and b.exit_code == 0, a.output + b.output
    da, db = (json.loads((tmp_path / n).read_text()) for n in ("a.json", "b.json"))
    assert "fresh" not in da and da["turn_cycle"] == db["turn_cycle"]
    assert da["chains"][0]["trace"][-1]["evaluations"] == db["chains"][0]["trace"][-1][
        "evaluations"]


@pytest.mark.parametrize("extra", [
    ["--step-noise", "-0.3,1"], ["--step-noise", "0.3,500"], ["--step-noise", "abc"],
    ["--step-noise", "0.3,1", "--walks", "0"], ["--step-noise", "0.3,1", "--walks", "100000"],
    ["--step-noise", "0.3,1", "--quantile", "0"], ["--step-noise", "0.3,1", "--quantile", "1.5"],
    ["--walks", "16"], ["--quantile", "0.5"],
])
def test_bad_step_noise_input_is_one_line_and_exit_2(extra):
    res = CliRunner().invoke(main, ["optimize", "--evaluations", "100", *extra])
    assert res.exit_code == 2, res.output
    assert len(res.output.strip().splitlines()) == 1


def test_draw_normals_refuses_absurd_walks():
    rng = np.random.default_rng(0)
    assert draw_normals(rng, 3, 10).shape == (3, 10, 3)
    for walks in (0, 5000):
        with pytest.raises(InputError):
            draw_normals(rng, walks, 200)
    with pytest.raises(InputError):
        draw_normals(rng, 4096, 2000)  # too many noisy gait cycles to hold


def test_the_best_known_sweep_collapses_under_step_noise():
    """Why the search must score noisy walks: the sharp best known turn cycle on the shifted
    table (49 noise-free) covers little once every gait cycle varies."""
    genes = parse_turn_cycle("12:2,11:2,22:11,18:4,13:3,4:5,9:6,6:2,0:3")
    z = draw_normals(np.random.default_rng(0), 100, 200)
    fit = NoisyWalks(shifted_table().rows, NOISE, z).figures(genes[None])[2, 0]
    assert simulate(shifted_table().rows, genes).fitness[0] == 49
    assert fit.mean() < 20
