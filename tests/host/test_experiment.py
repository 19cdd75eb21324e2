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
    assert len(summary["runs"]) == 6  # 2 seeds x full, partial and the oracle control
    for r in summary["runs"]:
        assert r["generations"] == [0, 40, 80]
        assert len(r["coverage"]) == 3 and all(c <= summary["optimum"] for c in r["coverage"])
        assert len(r["final_model_error"]) == 32
        assert r["reached_optimum_at"] is None or r["reached_optimum_at"] in r["generations"]
    comp = summary["comparison"]
    assert set(comp["methods"]) == {"full", "partial", "oracle"}
    assert 0 <= comp["tests"]["reached_optimum_fisher_exact_p"] <= 1
    lines = (out / "log.jsonl").read_text().splitlines()
    assert len(lines) == 18  # 2 seeds x 3 methods x 3 punctuations
    assert {json.loads(x)["method"] for x in lines} == {"full", "partial", "oracle"}
    for name in ("coverage_full.png", "coverage_partial.png", "coverage_oracle.png",
                 "coverage_means.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
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


def test_full_run_once_with_partial_is_what_full_alone_gives(finished, tmp_path):
    """With the whole-table fit and no model GA, recombination has nothing to act on: the
    experiment runs partial once and reports it for full too. Full run on its own must give
    the same runs, punctuation for punctuation."""
    out, text = finished
    summary = json.loads((out / "summary.json").read_text())
    assert summary["same_runs"] == [{"method": "full", "same_as": "partial",
                                     "why": summary["same_runs"][0]["why"]}]
    assert "full is the same run as partial" in text
    res = _run(["experiment", *SMALL, "--methods", "full", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    alone = json.loads((tmp_path / "summary.json").read_text())
    assert alone["same_runs"] == []
    keep = ("seed", "coverage", "operational", "final_model", "final_model_error")
    assert [{k: r[k] for k in keep} for r in alone["runs"]] == \
        [{k: r[k] for k in keep} for r in summary["runs"] if r["method"] == "full"]
    logged = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines()]
    assert all(r["same_run_as"] == "partial" for r in logged if r["method"] == "full")


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
    res = _run(["experiment", *SMALL, "--methods", "full,partial", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    without = json.loads((tmp_path / "summary.json").read_text())

    def runs(s):
        return [{k: v for k, v in r.items() if k != "reached_optimum_at"}
                for r in s["runs"] if r["method"] != "oracle"]

    # the control changes nothing for the two methods, and is compared on the same seeds
    assert runs(summary) == runs(without)
    assert (summary["comparison"]["tests"]["final_coverage_wilcoxon"]
            == without["comparison"]["tests"]["final_coverage_wilcoxon"])
    comp = summary["comparison"]["methods"]
    oracle_final = {r["seed"]: r["coverage"][-1] for r in summary["runs"]
                    if r["method"] == "oracle"}
    for m in ("full", "partial"):
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
    first = [x for x in lines if json.loads(x)["seed"] == 0 and json.loads(x)["method"] == "full"]
    partial = [x for x in lines if json.loads(x)["seed"] == 1 and json.loads(x)["method"] == "full"]
    (tmp_path / "log.jsonl").write_text("\n".join(first + partial[:1]) + "\n")
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
