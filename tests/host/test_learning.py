"""Learning the robot in few tests: whole-table correction, informative tests, robot time."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pac_host.coverage import parse_turn_cycle
from pac_host.errors import InputError
from pac_host.experiments.experiment import punctuations_to, robot_time_report
from pac_host.learning import model_fit, pal, test_selection
from pac_host.learning.robot_time import GAIT_PERIOD_S, PLACE_S, seconds_of_tests
from pac_host.model import measured_table, robots, shifted_table
from pac_host.model.effects import effective_rows
from pac_host.model.table import save_table
from pac_host.search import cga

TESTS = np.array([[[12, 20], [3, 8], [19, 6]], [[12, 9], [22, 7], [0, 0]],
                  [[14, 30], [7, 5], [0, 0]]])


def _observe(actual, tests=TESTS, noise=0.0, seed=0):
    res = pal.SimulatedRobot(actual).run_tests(tests)
    rng = np.random.default_rng(seed)
    return [model_fit.Observed(model_fit.expand_ids(t, 200),
                               r.poses + rng.normal(size=r.poses.shape) * noise)
            for t, r in zip(tests, res, strict=True)]


def test_structure_corrects_rows_no_test_used():
    obs = _observe(shifted_table())
    post = model_fit.correct(measured_table(), obs, np.random.default_rng(0))
    assert [e.name for e in post.selected] == ["turn_shift"]
    unused = post.evidence == 0
    assert unused.sum() > 10
    # the unused rows move to the robot's too: the shift seen on the used rows applies to all
    assert np.abs(post.mean - shifted_table().rows).max() < 1e-6
    assert np.abs(measured_table().rows - shifted_table().rows)[unused].max() > 1.0


def test_rows_alone_pin_used_rows_and_leave_the_others():
    obs = _observe(shifted_table())
    post = model_fit.correct(measured_table(), obs, np.random.default_rng(0), structure="none")
    used = post.evidence > 0
    assert np.abs(post.mean - shifted_table().rows)[used].max() < 1e-3
    assert np.abs(post.mean - measured_table().rows)[~used].max() < 1e-9
    # evidence: one per observed step of that gait
    ids = np.concatenate([o.gait_ids for o in obs])
    assert post.evidence.tolist() == np.bincount(ids, minlength=32).tolist()


def test_noisy_paths_sequence_effects_and_posterior_spread():
    actual = robots.build("library_on_changed")
    obs = _observe(actual, noise=0.5, seed=3)
    post = model_fit.correct(measured_table(), obs, np.random.default_rng(0))
    assert "transition" in {e.name for e in post.effects}  # kept as an effect of the model
    assert post.sigma.min() > 0.3  # the tracker's noise is seen as noise
    truth = effective_rows(actual.rows, [e for e in actual.effects if e.name != "transition"])
    used = post.evidence >= 20
    err_used = np.abs(post.mean - truth)[used].mean(axis=0)
    err_base = np.abs(measured_table().rows - truth)[used].mean(axis=0)
    assert np.all(err_used < 0.5 * err_base)
    sd = post.sd
    assert sd[post.evidence == 0].mean() > 3 * sd[used].mean()


def test_posterior_samples_vary_only_the_rows_asked():
    post = model_fit.correct(measured_table(), _observe(robots.build("noisy_rows")),
                             np.random.default_rng(0))
    pop = post.sample(8, np.random.default_rng(1), rows=[3, 12])
    assert np.array_equal(pop[0], post.mean)
    moved = np.abs(pop - post.mean).max(axis=(0, 2)) > 0
    assert moved.nonzero()[0].tolist() == [3, 12]
    assert post.sample(8, np.random.default_rng(1)).std(axis=0).min() > 0


def test_informative_tests_pick_where_the_models_disagree():
    rng = np.random.default_rng(0)
    best = np.array([[12, 30], [0, 0]])
    agree = np.array([[12, 10], [15, 10]])  # straight rows: every model agrees
    split = np.array([[12, 10], [3, 12]])  # row 3: the models disagree on it
    pert = np.stack([np.array([[12, 31], [0, 0]]), np.array([[12, 29], [0, 0]])])
    models = np.broadcast_to(measured_table().rows, (12, 32, 3)).copy()
    models[:, 3, 2] += rng.normal(size=12) * 6.0
    pop = np.stack([best, agree, split, agree])
    var = models.var(axis=0).sum(axis=-1)
    tests = test_selection.choose(best, pert, pop, models, var, 200)
    assert np.array_equal(tests[0], best)
    assert np.array_equal(tests[1], split)
    assert len(tests) == 3


def test_with_no_candidate_but_the_best_there_are_still_three_tests():
    best = np.array([[12, 30], [0, 0]])
    models = np.broadcast_to(measured_table().rows, (4, 32, 3)).copy()
    var = models.var(axis=0).sum(axis=-1)
    same = np.stack([best, best])  # perturbations that changed nothing, a converged population
    hopeful = np.array([[3, 5], [0, 0]])  # which takes one of the two places
    tests = test_selection.choose(best, same, np.stack([best] * 4), models, var, 200,
                                  hopeful=hopeful)
    assert len(tests) == 3 and np.array_equal(tests[1], hopeful)
    assert len(test_selection.choose(best, same, np.stack([best] * 4), models, var, 200)) == 3


def test_rows_tests_walk_an_uncertain_row_no_candidate_uses():
    rng = np.random.default_rng(0)
    best = np.array([[12, 30], [7, 4]])
    agree = np.array([[12, 10], [15, 10]])
    pert = np.stack([np.array([[12, 31], [7, 4]]), np.array([[12, 29], [7, 4]])])
    models = np.broadcast_to(measured_table().rows, (12, 32, 3)).copy()
    models[:, 3, 2] += rng.normal(size=12) * 6.0  # row 3: unknown, and no candidate walks it
    var = models.var(axis=0).sum(axis=-1)
    pop = np.stack([best, agree, agree])
    walked = [set(t[:, 0].tolist()) for t in
              test_selection.choose(best, pert, pop, models, var, 200)]
    assert not any(3 in ids for ids in walked)
    tests = test_selection.choose(best, pert, pop, models, var, 200, teach=4)
    # the pair nearest row 3 in turn (id 7, strength 7, the same side) takes it
    assert np.array_equal(tests[0], best) and len(tests) == 3
    assert np.array_equal(tests[1], np.array([[12, 30], [3, 4]]))


def test_choose_tests_gives_the_teaching_variants_only_with_rows(monkeypatch):
    cfg = pal.PALConfig(**{**pal.PAPER, "cga_population": 8, "model_population": 6})
    state = pal.initial_state(measured_table(), np.random.default_rng(0), cfg)
    taught, choose = [], test_selection.choose

    def spy(*args, teach=0, **kw):
        taught.append(teach)
        return choose(*args, teach=teach, **kw)

    monkeypatch.setattr(test_selection, "choose", spy)
    for tests in ("informative", "rows", "paper"):
        pal.choose_tests(state, np.random.default_rng(9), pal.replace(cfg, tests=tests))
    # the default (evolve's and experiment's, measured best in docs/explanation/learning.md) is rows
    pal.choose_tests(state, np.random.default_rng(9),
                     pal.PALConfig(cga_population=8, model_population=6))
    # the paper's tests choose nothing
    assert taught == [0, test_selection.TEACHING_ROWS, test_selection.TEACHING_ROWS]


def test_operational_takes_any_tested_turn_cycle_that_did_better():
    class Robot:
        def run_tests(self, tests):
            return [pal.TestResult(f, f, f, 0) for f in (4, 2, 9)]

    cfg = pal.PALConfig(**{**pal.PAPER, "cga_population": 8, "model_population": 4,
                           "model_generations": 1, "operational": "tested"})
    rng = np.random.default_rng(0)
    state = pal.initial_state(measured_table(), rng, cfg)
    state, rec = pal.punctuate(state, Robot(), rng, cfg)
    assert rec["operational_fitness"] == 9 and rec["operational"] == rec["tests"][2]


FIT = pal.PALConfig(cga_population=24, model_population=8, generations=40, interval=20,
                    model_generations=0, correction="fit", tests="informative",
                    operational="tested")


def test_fit_correction_learns_the_whole_table_in_pal_and_resumes_bit_for_bit():
    rng = np.random.default_rng(5)
    state = pal.initial_state(measured_table(), rng, FIT)
    robot = pal.SimulatedRobot(shifted_table())
    state, rec = pal.punctuate(state, robot, rng, FIT)
    assert np.abs(state.models[0] - shifted_table().rows).max() < 1e-6
    assert rec["structure"] == ["turn_shift:k=1"] and rec["model_fitness"] == "steps"
    assert rec["robot_seconds"] == pytest.approx(float(seconds_of_tests(
        np.array([parse_turn_cycle(t) for t in rec["tests"]]), 200).sum()), abs=1e-3)
    state, _ = pal.advance_cga(state, 20, rng, FIT)
    doc = json.loads(json.dumps(pal.state_to_json(state, rng)))
    again, rng2 = pal.state_from_json(doc)
    a, rec_a = pal.punctuate(state, robot, rng, FIT)
    b, rec_b = pal.punctuate(again, robot, rng2, FIT)
    assert rec_a == rec_b and np.array_equal(a.models, b.models)


def test_fit_correction_needs_paths():
    class Counts:
        def run_tests(self, tests):
            return [pal.TestResult(3, 3, 3, 0)] * 3

    rng = np.random.default_rng(0)
    state = pal.initial_state(measured_table(), rng, FIT)
    with pytest.raises(InputError, match="observed paths"):
        pal.punctuate(state, Counts(), rng, FIT)


def test_robot_time_counts_walking_and_placing():
    tc = np.array([[[3, 2], [20, 1]]])  # 3, 3, 20, 3, 3, 20, ...
    ids = [3, 3, 20] * 4
    assert seconds_of_tests(tc, 12)[0] == pytest.approx(GAIT_PERIOD_S[ids].sum() + PLACE_S)
    assert seconds_of_tests(np.array([[[3, 0]]]), 12)[0] == PLACE_S  # stands still


def test_punctuations_to_target_and_report():
    assert punctuations_to([3, 9, 27, 31], 0.9 * 30) == 3
    assert punctuations_to([3, 9], 27) is None
    runs = [{"method": "m", "coverage": c, "robot_hours": [0.2 * (i + 1) for i in range(4)],
             "punctuations_to_target": punctuations_to(c, 27)}
            for c in ([3, 27, 29, 30], [3, 9, 28, 29], [1, 1, 1, 1])]
    rep = robot_time_report(runs, 30)["methods"]["m"]
    assert rep["reached_target"] == 2 and rep["median_punctuations_to_target"] == 3
    assert rep["punctuations_to_target_range"] == [2, 3]
    assert rep["median_robot_hours_to_target"] == pytest.approx(0.6)
    assert rep["ended_at_final_target"] == 2  # 30 and 29 are >= 95% of 30; 1 is not
    runs[1]["coverage"][-1] = 28
    assert robot_time_report(runs, 30)["methods"]["m"]["ended_at_final_target"] == 1


def test_robots_are_what_the_docs_say():
    m = measured_table().rows
    asym = robots.build("asymmetric").rows
    assert np.allclose(asym[:16, 1:], 0.75 * m[:16, 1:])  # right turns weaker
    assert np.allclose(asym[16:31], m[[16] + list(range(16, 30))])  # left one strength harder
    noisy = robots.build("noisy_rows").rows
    assert np.all(np.abs(noisy - m).max(axis=1) > 0)  # every row differs
    lib = robots.build("library_on_changed")
    assert {e.name for e in lib.effects} == {"transition", "yaw_bias"}
    assert robots.build("noisy_rows", 1).rows.tolist() != noisy.tolist()
    with pytest.raises(InputError):
        robots.build("nope")


def test_choose_tests_keeps_the_papers_stream_for_the_paper():
    cfg = pal.PALConfig(**{**pal.PAPER, "cga_population": 8, "model_population": 4})
    state = pal.initial_state(measured_table(), np.random.default_rng(0), cfg)
    a = pal.choose_tests(state, np.random.default_rng(9), cfg)
    rng = np.random.default_rng(9)
    b = np.concatenate([state.cga_pop[:1], pal.perturbations(state.cga_pop[0], rng, cfg)])
    assert np.array_equal(a, b)
    _ = cga  # the CGA population is what the candidates come from


def test_experiment_on_a_robot_file_reports_robot_time(tmp_path):
    from click.testing import CliRunner

    from pac_host.cli.main import main

    robot = tmp_path / "robot.json"
    save_table(robots.build("library_on_changed"), robot)
    out = tmp_path / "exp"
    res = CliRunner().invoke(main, [
        "experiment", "--seeds", "2", "--generations", "40", "--initial-generations", "20",
        "--optimum-runs", "1", "--optimum-generations", "30", "--methods", "partial,oracle",
        "--actual", str(robot), "--correction", "fit", "--model-generations", "0",
        "--tests", "informative", "--operational", "tested", "--best-known", "40",
        "--optimum-evaluations", "20000", "--search-evaluations", "5000", "--shapes",
        "none",
        "--out", str(out)], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    s = json.loads((out / "summary.json").read_text())
    assert {e["name"] for e in s["actual"]["effects"]} == {"transition", "yaw_bias"}
    assert s["pal_config"]["correction"] == "fit"
    rt = s["robot_time"]
    # the file is the built-in robot: its record (50) beats the lower --best-known given
    assert rt["best_known"] == 50 and set(rt["methods"]) == {"partial", "oracle"}
    assert s["best_known"]["used"] == "built-in" and s["best_known"]["given"] == 40
    assert s["best_known"]["built_in"]["robot"] == "library_on_changed"
    for r in s["runs"]:
        assert len(r["robot_hours"]) == 2 and 0 < r["robot_hours"][0] < r["robot_hours"][1]
        assert r["punctuations_to_target"] is None  # 45 is out of reach in 40 generations
    assert (out / "robot_time.png").read_bytes()[:4] == b"\x89PNG"
    assert "punctuations" in res.output and "robot hours" in res.output
    bad = CliRunner().invoke(main, ["experiment", "--best-known", "0", "--out", str(out)])
    assert bad.exit_code == 2 and "--best-known must be at least 1" in bad.output


def test_independent_row_errors_are_not_taken_for_an_effect():
    # each row wrong on its own: an effect fitted to some rows must not move the others
    actual = robots.build("noisy_rows")
    tests = cga.random_population(np.random.default_rng(1), 3)
    post = model_fit.correct(measured_table(), _observe(actual, tests), np.random.default_rng(0))
    assert post.selected == ()
    unused = post.evidence == 0
    # (the smooth prior may move them by a common offset the walked rows share by chance: a
    # hundredth of their errors here)
    moved = np.abs(post.mean - measured_table().rows)[unused].max(axis=0)
    assert np.all(moved < 0.05 * np.abs(actual.rows - measured_table().rows)[unused].mean(axis=0))
    assert np.abs(post.mean - actual.rows)[~unused].max() < 1e-6
