"""The experiment command end to end (small sizes): files, resume, jobs, and the CLI's errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import parse_turn_cycle
from pac_host.coverage.placement import HAND, WALKS, placed_fitness
from pac_host.coverage.placement import summary as summary_of
from pac_host.experiments.experiment import STAGE_PLACED
from pac_host.model import shifted_table

SMALL = ["--seeds", "2", "--generations", "80", "--initial-generations", "30",
         "--optimum-runs", "2", "--optimum-generations", "60", "--optimum-evaluations", "20000",
         "--search-evaluations", "5000"]


def _run(args):
    return CliRunner().invoke(main, args, catch_exceptions=False)


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    out = tmp_path_factory.mktemp("exp")
    res = _run(["experiment", *SMALL, "--out", str(out)])
    assert res.exit_code == 0, res.output
    return out, res.output


def test_experiment_writes_summary_log_and_plots(finished):
    out, text = finished
    summary = json.loads((out / "summary.json").read_text())
    assert summary["format"] == "pac-experiment/1"
    assert len(summary["runs"]) == 4  # 2 seeds x partial and the oracle control
    for r in summary["runs"]:
        assert r["generations"] == [0, 40, 80]
        assert len(r["coverage"]) == 3 and all(c <= summary["optimum"] for c in r["coverage"])
        assert len(r["final_model_error"]) == 32
        assert r["reached_optimum_at"] is None or r["reached_optimum_at"] in r["generations"]
    comp = summary["comparison"]
    assert set(comp["methods"]) == {"partial", "oracle"}
    lines = (out / "log.jsonl").read_text().splitlines()
    assert len(lines) == 12  # 2 seeds x 2 methods x 3 punctuations
    assert {json.loads(x)["method"] for x in lines} == {"partial", "oracle"}
    for name in ("coverage_partial.png", "coverage_oracle.png", "coverage_means.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (out / "coverage_full.png").exists()
    assert "seeds reached the optimum" in text and "summary:" in text
    # each final turn cycle is also walked on the actual robot from drawn start poses
    rows = shifted_table().rows
    for r in summary["runs"]:
        genes = parse_turn_cycle(r["operational"])
        fit = placed_fitness(rows, genes, HAND, WALKS, np.random.default_rng(
            np.random.SeedSequence([0, r["seed"], STAGE_PLACED, 0])))
        assert r["placed"] == summary_of(fit)
    for m, s in summary["robot_time"]["methods"].items():
        want = np.mean([r["placed"]["mean"] for r in summary["runs"] if r["method"] == m])
        assert s["mean_placed_fitness"] == pytest.approx(want, abs=0.006)
    assert "placed by hand" in text


def test_the_default_profile_compares_methods_that_differ(finished):
    """With the whole-table fit and no model GA, recombination has nothing to act on: the
    default's methods are partial and the oracle (--profile paper's are full, partial and
    the oracle: tests/host/test_profiles.py), and their runs differ."""
    out, text = finished
    summary = json.loads((out / "summary.json").read_text())
    assert summary["config"]["methods"] == ["partial", "oracle"]
    assert "same_runs" not in summary and "tests" not in summary["comparison"]
    by = {(r["method"], r["seed"]): r for r in summary["runs"]}
    assert any(by["partial", s]["coverage"] != by["oracle", s]["coverage"] for s in (0, 1))
    assert "    full:" not in text


@pytest.mark.parametrize("methods", ["full,partial", "full", "full,partial,oracle"])
def test_full_where_no_model_ga_runs_is_one_line_and_exit_2(tmp_path, methods):
    res = CliRunner().invoke(main, ["experiment", *SMALL, "--methods", methods,
                                    "--out", str(tmp_path)])
    assert res.exit_code == 2, res.output
    line, = res.output.strip().splitlines()
    assert line.startswith(f"pac-host: error: --methods {methods}: full differs from partial "
                           "only in the model GA's recombination")
    assert "--profile paper, or --model-generations N" in line
    assert not (tmp_path / "log.jsonl").exists()


def test_model_fitness_coverage_where_the_model_is_fitted_is_one_line_and_exit_2(tmp_path):
    """--model-fitness would do nothing where the model is fitted to every observed step: it
    is refused there, before anything is written, and taken under the paper profile."""
    res = CliRunner().invoke(main, ["experiment", *SMALL, "--model-fitness", "coverage",
                                    "--out", str(tmp_path)])
    assert res.exit_code == 2, res.output
    line, = res.output.strip().splitlines()
    assert line.startswith("pac-host: error: --model-fitness coverage scores the model GA's")
    assert "--profile paper or --correction ga" in line
    assert not any(tmp_path.iterdir())
    ok = CliRunner().invoke(main, ["experiment", *SMALL, "--correction", "ga",
                                   "--model-fitness", "coverage", "--out", str(tmp_path / "ga")])
    assert ok.exit_code == 0, ok.output


def test_experiment_measures_against_the_best_known_on_a_built_in_robot(finished):
    """On the shifted robot at budget 200 robot time counts against the package's record (49),
    not the short run's own optimum; summary.json says which it used."""
    out, text = finished
    summary = json.loads((out / "summary.json").read_text())
    best = summary["best_known"]
    assert summary["optimum"] < 49
    assert best["fitness"] == summary["robot_time"]["best_known"] == 49
    assert best["used"] == "built-in" and best["optimum"] == summary["optimum"]
    assert best["built_in"] == {"robot": "shifted", "fitness": 49,
                                "turn_cycle": "12:2,11:2,22:11,18:4,13:3,4:5,9:6,6:2,0:3"}
    for r in summary["runs"]:
        target = next((i + 1 for i, c in enumerate(r["coverage"]) if c >= 0.9 * 49), None)
        assert r["punctuations_to_target"] == target
    assert "best known 49 (the best known on the built-in robot shifted" in text


def test_best_known_follows_the_actual_robot_and_budget():
    from pac_host.experiments.experiment import ExperimentConfig, best_known_on
    from pac_host.learning.pal import PALConfig
    from pac_host.model import Effect, measured_table, robots

    cfg = ExperimentConfig()
    assert best_known_on(robots.build("noisy_rows"), cfg, 30)["fitness"] == 54
    assert best_known_on(measured_table(), cfg, 30)["built_in"]["robot"] == "measured"
    # its own optimum where it is higher; --best-known where that is
    assert best_known_on(shifted_table(), cfg, 51)["used"] == "optimum"
    given = best_known_on(shifted_table(), ExperimentConfig(best_known=60), 30)
    assert (given["fitness"], given["used"]) == (60, "given")
    # another budget, or the robot with an effect added, has no record
    other = ExperimentConfig(pal=PALConfig(budget=150))
    assert best_known_on(shifted_table(), other, 30)["built_in"] is None
    skewed = shifted_table().with_effects((Effect("yaw_bias", {"delta": 1.0}),))
    assert best_known_on(skewed, cfg, 30) == {
        "fitness": 30, "used": "optimum", "source": "this experiment's optimum on the actual "
        "robot", "optimum": 30, "built_in": None, "given": None}


def test_the_plots_name_what_ran(finished, figure_labels, tmp_path):
    """The default profile runs no CGA between punctuations and no model GA: the curves are
    against punctuations and PAL is not called partial recombination; the paper's are
    against CGA generations."""
    from pac_host import plots

    out, _ = finished
    summary = json.loads((out / "summary.json").read_text())
    seen = figure_labels
    plots.experiment_plots(summary, tmp_path)
    for name in ("coverage_partial.png", "coverage_oracle.png", "coverage_means.png"):
        assert seen[name][0] == "punctuations (3 robot tests each)", name
    assert "partial recombination" not in seen["coverage_partial.png"][1]
    assert "fitted to every observed step" in seen["coverage_partial.png"][1]
    paper = {**summary, "pal_config": {**summary["pal_config"], "search": "cga",
                                       "correction": "ga", "model_generations": 40}}
    plots.experiment_plots(paper, tmp_path)
    assert seen["coverage_means.png"][0] == "CGA generation"
    assert seen["coverage_partial.png"][1].startswith("PAL with partial recombination")


def test_optimum_is_the_best_known_on_the_actual_robot(finished):
    out, _ = finished
    summary = json.loads((out / "summary.json").read_text())
    opt = json.loads((out / "optimum.json").read_text())
    best_seen = max(max(r["coverage"]) for r in summary["runs"])
    assert opt["observed"] == best_seen
    assert opt["searched"] == max(r["fitness"] for r in opt["runs"]) and len(opt["runs"]) == 2
    assert summary["optimum"] == opt["fitness"] == max(opt["searched"], best_seen)


def test_oracle_control_runs_the_cga_on_the_actual_table(finished, tmp_path):
    out, text = finished
    res = _run(["experiment", *SMALL, "--methods", "partial", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    without = json.loads((tmp_path / "summary.json").read_text())

    def runs(s):
        return [{k: v for k, v in r.items() if k != "reached_optimum_at"}
                for r in s["runs"] if r["method"] != "oracle"]

    # the control changes nothing for the method, and is compared on the same seeds
    assert runs(summary) == runs(without)
    comp = summary["comparison"]["methods"]
    oracle_final = {r["seed"]: r["coverage"][-1] for r in summary["runs"]
                    if r["method"] == "oracle"}
    for m in ("partial",):
        finals = {r["seed"]: r["coverage"][-1] for r in summary["runs"] if r["method"] == m}
        assert comp[m]["matched_oracle"] == sum(finals[s] >= oracle_final[s] for s in finals)
    assert "matched_oracle" not in comp["oracle"] and "oracle" not in without["comparison"]
    recs = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines()]
    oracle = [r for r in recs if r["method"] == "oracle"]
    assert len(oracle) == 6
    for r in oracle:  # a perfect model: every test's figures predicted exactly
        assert [p["blocks_covered"] for p in r["predicted"]] == [
            o["blocks_covered"] for o in r["observed"]]
        assert [p["fitness"] for p in r["predicted"]] == [o["fitness"] for o in r["observed"]]
        assert all(e["F"] == e["T"] == e["dH"] == 0 for e in r["model_error"])
    assert any(p != {k: o[k] for k in p}  # the measured model, by contrast, is wrong
               for r in recs if r["method"] == "partial"
               for p, o in zip(r["predicted"], r["observed"], strict=True))
    assert "  oracle: " in text and "as good as the oracle on" in text


def test_jobs_do_not_change_results(finished, tmp_path):
    out, _ = finished
    res = _run(["experiment", *SMALL, "--jobs", "2", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    a = json.loads((out / "summary.json").read_text())["runs"]
    b = json.loads((tmp_path / "summary.json").read_text())["runs"]
    assert a == b


def test_interrupted_experiment_resumes_to_the_same_summary(finished, tmp_path):
    out, _ = finished
    lines = (out / "log.jsonl").read_text().splitlines()
    # keep one complete run and half of another, as if killed mid-run
    first = [x for x in lines
             if json.loads(x)["seed"] == 0 and json.loads(x)["method"] == "partial"]
    partial = [x for x in lines
               if json.loads(x)["seed"] == 1 and json.loads(x)["method"] == "partial"]
    (tmp_path / "log.jsonl").write_text("\n".join(first + partial[:1]) + "\n")
    (tmp_path / "config.json").write_bytes((out / "config.json").read_bytes())
    res = _run(["experiment", *SMALL, "--out", str(tmp_path)])
    assert res.exit_code == 2 and "--resume" in res.output
    res = _run(["experiment", *SMALL, "--out", str(tmp_path), "--resume"])
    assert res.exit_code == 0, res.output
    a = json.loads((out / "summary.json").read_text())
    b = json.loads((tmp_path / "summary.json").read_text())
    key = lambda r: (r["method"], r["seed"])  # noqa: E731
    assert [(key(r), r["coverage"], r["final_model_error"]) for r in a["runs"]] == \
        [(key(r), r["coverage"], r["final_model_error"]) for r in b["runs"]]
    assert sorted((tmp_path / "log.jsonl").read_text().splitlines()) == sorted(lines)


@pytest.mark.parametrize("args, message", [
    (["simulate", "--turn-cycle", "12:14,40:2"], "gait cycle id 40 outside 0..31"),
    (["simulate", "--turn-cycle", "12:99"], "repetitions 99 outside 0..63"),
    (["simulate", "--turn-cycle", "12:9", "--budget", "-3"], "--budget must be 0..65535"),
    (["simulate", "--turn-cycle", "12:9", "--effect", "gremlin:x=1"], "unknown effect 'gremlin'"),
    (["simulate", "--turn-cycle", "12:9", "--table", "nope.json"], "nope.json: cannot read"),
    (["table", "show", "--table", "shiftd"], "shiftd: cannot read"),
    (["experiment", "--seeds", "0", "--out", "x"], "--seeds must be 1..10000, got 0"),
    (["experiment", "--methods", "full,half", "--out", "x"], "--methods takes full"),
    (["experiment", "--methods", "oracle,oracle", "--out", "x"], "(each once)"),
    (["experiment", "--optimum-runs", "0", "--out", "x"], "--optimum-runs must be 1..1000, got 0"),
])
def test_bad_input_is_one_line_and_exit_2(args, message):
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2, res.output
    assert message in res.output
    assert "Traceback" not in res.output
    assert len(res.output.strip().splitlines()) == 1


def test_malformed_table_file(tmp_path):
    (tmp_path / "t.json").write_text('{"format": "pac-gait-table/1", "cycles": []}')
    res = CliRunner().invoke(main, ["table", "show", "--table", str(tmp_path / "t.json")])
    assert res.exit_code == 2 and "ids missing" in res.output


def test_simulate_json_output():
    res = _run(["simulate", "--table", "shifted", "--turn-cycle", "12:14,3:10,12:3,19:10",
                "--budget", "30", "--json"])
    doc = json.loads(res.output)
    assert set(doc) == {"poses", "blocks_covered", "blocks_covered_once", "fitness",
                        "repeat_visits"}
    assert len(doc["poses"]) == 31 and doc["poses"][0] == [45.0, 30.0, 90.0]


def test_table_export_then_use(tmp_path):
    path = tmp_path / "t.json"
    res = _run(["table", "export", str(path), "--table", "shifted",
                "--effect", "yaw_bias:delta=2"])
    assert res.exit_code == 0
    doc = json.loads(path.read_text())
    assert doc["effects"] == [{"name": "yaw_bias", "params": {"delta": 2.0}}]
    shown = _run(["table", "show", "--table", str(path)]).output
    assert "effect: yaw_bias:delta=2" in shown


def test_simulate_draws_the_path(tmp_path):
    png = tmp_path / "path.png"
    res = _run(["simulate", "--turn-cycle", "12:14,3:10,12:3,19:10", "--plot", str(png)])
    assert res.exit_code == 0
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 10_000


def _files(d):
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())} if d.exists() else None


def _one_line(res, words):
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pac-host: error:"), res.output
    assert words in lines[0], res.output


def test_resume_refuses_a_folder_without_an_experiment_and_writes_nothing(finished, tmp_path):
    out, _ = finished
    missing, empty, foreign = tmp_path / "missing", tmp_path / "empty", tmp_path / "foreign"
    empty.mkdir()
    foreign.mkdir()
    (foreign / "log.jsonl").write_bytes((out / "log.jsonl").read_bytes())  # no config.json
    other = tmp_path / "other"
    other.mkdir()
    (other / "config.json").write_text('{"format": "pac-evolve-config/1"}\n')
    for folder, words in ((missing, "no such directory"), (empty, "the directory is empty"),
                          (foreign, "no config.json there (not an experiment run)"),
                          (other, "not a pac-experiment-config/1 file")):
        before = _files(folder)
        _one_line(_run(["experiment", "--out", str(folder), "--resume"]), words)
        assert _files(folder) == before


def test_resume_refuses_options_that_differ_and_takes_the_saved_ones(finished, tmp_path):
    """--seeds 3 on a 2-seed run is refused by name, nothing written; a resume that gives no
    options runs with the saved ones (it says which) and leaves a finished run as it was."""
    import shutil

    out, _ = finished
    run = tmp_path / "run"
    shutil.copytree(out, run)
    before = _files(run)
    _one_line(_run(["experiment", "--out", str(run), "--resume", "--seeds", "3"]),
              "--seeds 3 differs from the saved run's 2; resume takes the saved options, "
              "drop --seeds or start a new --out")
    res = _run(["experiment", "--out", str(run), "--resume", "--seeds", "3", "--generations",
                "40", "--profile", "paper"])
    _one_line(res, "drop --seeds and --generations and --profile")
    assert _files(run) == before
    res = _run(["experiment", "--out", str(run), "--resume", "--seeds", "2", "--jobs", "2"])
    assert res.exit_code == 0, res.output
    took = res.output.splitlines()[0]
    assert took.startswith("resuming with the saved options") and "--generations 80" in took
    assert "--seeds" not in took  # typed, and the same
    after = _files(run)
    assert after["summary.json"] == before["summary.json"]
    assert sorted(after["log.jsonl"].splitlines()) == sorted(before["log.jsonl"].splitlines())
    saved = json.loads(after["config.json"])
    assert saved["options"]["seeds"] == 2 and "seeds" in saved["typed"]
    assert "jobs" not in saved["options"]  # how a run runs is not what it is

