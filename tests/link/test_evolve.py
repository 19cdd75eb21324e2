"""`pac-host evolve` end to end against the emulator on a real pseudo-terminal."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pac_host.coverage import START_POSE, coverage_of_poses
from pac_host.model import load_table, rollout, shifted_table

from .conftest import SMALL, evolve_against_pac_sim, invoke, read_jsonl, results

RUN_KEYS = {"run_id", "start_pose", "gait_cycles", "poses", "cycles_since_power_on"}


def test_evolve_writes_a_complete_log_and_the_model_error_falls(baseline):
    log = read_jsonl(baseline / "log.jsonl")
    assert [r["generation"] for r in log] == [0, 20, 40]
    for r in log:
        assert len(r["tests"]) == 3 and len(r["observed"]) == 3 and len(r["run_ids"]) == 3
        # the correction fits every observed step under a prior, not these three tests alone:
        # on them it may end a hair above where it started, never clearly above
        assert r["model_error_after"] <= 1.01 * r["model_error_before"]
        assert r["operational_fitness"] >= 0 and r["used_gait_ids"]
    # the model GA reduces the model's disagreement with the robot on the gait cycles used
    assert sum(r["model_error_after"] for r in log) < sum(r["model_error_before"] for r in log)
    assert log[0]["model_error_after"] < log[0]["model_error_before"]

    runs = read_jsonl(baseline / "runs.jsonl")
    assert [r["run_id"] for r in runs] == [i for r in log for i in r["run_ids"]]
    truth = shifted_table().rows
    power_on = 0
    for run, rec_obs in zip(runs, [o for r in log for o in r["observed"]], strict=True):
        assert set(run) == RUN_KEYS
        assert len(run["poses"]) == len(run["gait_cycles"]) == 100
        assert run["cycles_since_power_on"] == power_on  # the Stamp's count before the run
        power_on += 100
        # the observed path is the true robot's path plus the tracker's noise (0.5 cm, 1 deg)
        true = rollout(truth, START_POSE, run["gait_cycles"])
        err = np.array(run["poses"]) - true[1:]
        assert np.abs(err[:, :2]).max() < 3.5 and np.abs(err[:, 2]).max() < 7
        assert np.abs(np.array(run["start_pose"]) - START_POSE).max() < 7
        # the figures logged are those of the observed path
        cov = coverage_of_poses(np.vstack([[run["start_pose"]], run["poses"]]))
        assert rec_obs["blocks_covered"] == int(cov.blocks_covered)
        assert rec_obs["fitness"] == int(cov.fitness)

    obs = read_jsonl(baseline / "observations.jsonl")
    assert sum(o["type"] == "pose" for o in obs) == 9 * 100  # every pose logged
    table = load_table(baseline / "model.json")
    assert np.allclose(table.rows, np.array(log[-1]["model"]), atol=1e-6)
    tc = json.loads((baseline / "turn_cycle.json").read_text())
    assert tc["turn_cycle"] == log[-1]["operational"]
    for png in ("coverage_path.png", "learning_progress.png"):
        assert (baseline / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # a robot is placed by hand: the default profile searches for it (pac_host.coverage.placement)
    assert json.loads((baseline / "config.json").read_text())["placement"] == "0.5,1"
    # the host's seconds named for what ran: the fit with the model GA on top
    # (--model-generations) and the anytime search at the punctuation, a ranking between
    assert all(set(r["timing"]) == {"robot_s", "ranking_s", "model_fit_and_ga_and_search_s"}
               for r in log)
    assert all(r["search"]["evaluations"] % 7 == 0 for r in log if "search" in r)


def test_evolve_placement_default_follows_the_profile(tmp_path, figure_labels):
    """The paper's CGA scores from the exact start: with --profile paper the default is none,
    and an explicit placement error is refused (exit 2). Its model GA takes --method; the log,
    the printed model error and the figures name what ran."""

    seen = figure_labels
    out = tmp_path / "paper"
    args = [a for a in SMALL if a not in ("--search-evaluations", "20000")]
    res = invoke("evolve", "--out", str(out), "--generations", "0", "--profile", "paper",
                 "--method", "full", *args)
    assert res.exit_code == 0, res.output
    config = json.loads((out / "config.json").read_text())
    assert config["placement"] == "none" and config["method"] == "full"
    rec, = read_jsonl(out / "log.jsonl")
    assert rec["method"] == "full" and set(rec["timing"]) == {"robot_s", "cga_s", "model_ga_s"}
    assert (f"model error {rec['model_error_before']} -> {rec['model_error_after']} blocks "
            "(sum of the six coverage differences)") in res.output
    assert seen["learning_progress.png"][0] == "CGA generation"
    title = " ".join(seen["coverage_path.png"][1].split())  # folded to the figure's width
    assert title.startswith("punctuation 1: the model's best turn cycle, walked on the robot "
                            f"{rec['tests'][0]} (")
    res = invoke("evolve", "--out", str(tmp_path / "x"), "--generations", "0", "--profile",
                 "paper", "--placement-error", "0.5,1", *args)
    assert res.exit_code == 2 and "anytime" in res.output


@pytest.mark.slow
def test_the_default_profile_names_what_ran(tmp_path, figure_labels):
    """The default fits the model to every observed step and runs no model GA: --method, which
    chooses the model GA's recombination, is refused in one line (exit 2), given either way;
    without it the run's log, printed model error and figures name the fit and the search."""

    no_ga = [a for a in SMALL if a not in ("--model-generations", "15")]
    for method in ("full", "partial"):
        res = invoke("evolve", "--out", str(tmp_path / method), "--generations", "0",
                     "--method", method, *no_ga)
        assert res.exit_code == 2, res.output
        line, = res.output.strip().splitlines()
        assert line == ("pac-host: error: --method chooses the model GA's recombination, and "
                        "the default profile runs no model GA (it fits the model to every "
                        "observed step); use --profile paper, or --model-generations N to run "
                        "the GA on top")
        assert not (tmp_path / method).exists()
    res = invoke("evolve", "--out", str(tmp_path / "counts"), "--generations", "0",
                 "--model-fitness", "coverage", *no_ga)
    assert res.exit_code == 2 and not (tmp_path / "counts").exists()
    assert res.output.strip().startswith("pac-host: error: --model-fitness coverage scores")
    seen = figure_labels
    out = tmp_path / "fit"
    res = invoke("evolve", "--out", str(out), "--generations", "0", *no_ga)
    assert res.exit_code == 0, res.output
    rec, = read_jsonl(out / "log.jsonl")
    assert set(rec["timing"]) == {"robot_s", "ranking_s", "model_fit_and_search_s"}
    assert (f"model error {rec['model_error_before']} -> {rec['model_error_after']} cm (RMS "
            "residual of the observed steps") in res.output
    assert seen["learning_progress.png"][0] == "punctuations (3 robot tests each)"
    assert "model's best turn cycle" in " ".join(seen["coverage_path.png"][1].split())


def test_robot_that_stops_answering_then_resume(baseline, tmp_path):
    out = tmp_path / "cut"
    # 3 tests x 100 gait cycles per punctuation: gait cycle 650 is the 50th of g40-t0
    res = invoke("evolve", "--out", str(out), "--generations", "40", *SMALL,
                 "--mute-after", "650")
    assert res.exit_code == 1, res.output
    lines = res.output.strip().splitlines()
    assert lines[-1].startswith("pac-host: error:") and "stopped answering" in lines[-1]
    assert f"--resume {out}" in lines[-1] and "Traceback" not in res.output
    assert [r["generation"] for r in read_jsonl(out / "log.jsonl")] == [0, 20]
    obs = read_jsonl(out / "observations.jsonl")
    cut = [o for o in obs if o["type"] == "pose" and o["run_id"] == "g40-t0"]
    assert [o["cycle"] for o in cut] == list(range(1, 51))  # everything seen was logged

    res = invoke("evolve", "--resume", str(out))
    assert res.exit_code == 0, res.output
    assert results(out) == results(baseline)
    runs, base = read_jsonl(out / "runs.jsonl"), read_jsonl(baseline / "runs.jsonl")
    strip = [{k: v for k, v in r.items() if k != "cycles_since_power_on"} for r in runs]
    assert strip == [{k: v for k, v in r.items() if k != "cycles_since_power_on"} for r in base]
    assert runs[6]["cycles_since_power_on"] == 0  # a fresh power-on after the resume


def test_resume_of_a_finished_run_changes_nothing(baseline, tmp_path):
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(baseline, out)
    res = invoke("evolve", "--resume", str(out))
    assert res.exit_code == 0, res.output
    assert results(out) == results(baseline)


def test_bad_input_is_one_line(tmp_path):
    def one_line(res, code, words):
        assert res.exit_code == code, res.output
        last = res.output.strip().splitlines()[-1]
        assert last.startswith("pac-host: error:") and words in last, res.output
        assert "Traceback" not in res.output

    one_line(invoke("evolve", "--generations", "0"), 2, "--out DIR is required")
    one_line(invoke("evolve", "--resume", str(tmp_path)), 2, "no config.json")
    one_line(invoke("evolve", "--out", str(tmp_path / "o"), "--observer", "webcam"), 2,
             "--observer: expected")
    one_line(invoke("evolve", "--out", str(tmp_path / "o"), "--sim-noise", "x"), 2,
             "--sim-noise")
    one_line(invoke("evolve", "--out", str(tmp_path / "o"), "--port", "/dev/null",
                    "--observer", "manual"), 2, "not a serial device")
    (tmp_path / "used").mkdir()
    (tmp_path / "used" / "state.json").write_text('{}\n')
    one_line(invoke("evolve", "--out", str(tmp_path / "used")), 2, "use --resume")


def test_a_resumed_config_of_the_wrong_type_is_one_line(baseline, tmp_path):
    """A hand-edited config.json is checked field by field against its type before the run
    resumes; the run's files stay as they were."""
    import shutil

    for name, value, words in (("finish_moves", "yes", "finish_moves must be true or false"),
                               ("explore", "x", "explore must be a number"),
                               ("generations", 40.5, "generations must be an integer"),
                               ("interval", True, "interval must be an integer"),
                               ("model_generations", "a", "an integer or null"),
                               ("robot", [], "robot must be an object")):
        out = tmp_path / name
        shutil.copytree(baseline, out)
        doc = json.loads((out / "config.json").read_text())
        doc[name] = value
        (out / "config.json").write_text(json.dumps(doc))
        before = {p.name: p.read_bytes() for p in out.iterdir()}
        res = invoke("evolve", "--resume", str(out))
        assert res.exit_code == 2, res.output
        last = res.output.strip().splitlines()[-1]
        assert last.startswith("pac-host: error:") and words in last, res.output
        assert "Traceback" not in res.output
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.slow
def test_evolve_against_a_pac_sim_process_with_its_tracker(baseline, tmp_path):
    """The real-robot path: --port and --observer, here a separate pac-sim process whose world
    is placed through its tracker (--placer tracker) instead of by a person."""
    out = tmp_path / "proc"
    evolve_against_pac_sim(out, 40)
    # the same robot, the same seed: the same results as with the built-in emulator (whose
    # true table the log may also compare the model with)
    base = results(baseline)
    for r in base["log"]:
        del r["true_error_on_used"]
    assert results(out) == base
    assert (out / "runs.jsonl").read_text() == (baseline / "runs.jsonl").read_text()


def test_evolve_with_manual_counts(tmp_path):
    out = tmp_path / "hand"
    typed = "five 3 2\n5 3 2\n4 4 4\n6 2 3\n"  # the first reply is asked again
    res = invoke("evolve", "--out", str(out), "--generations", "0", *SMALL,
                 "--observer", "manual", input=typed)
    assert res.exit_code == 0, res.output
    assert "'five 3 2' is not 3 whole numbers" in res.output
    rec = read_jsonl(out / "log.jsonl")[0]
    assert [(o["blocks_covered"], o["blocks_covered_once"], o["fitness"])
            for o in rec["observed"]] == [(5, 3, 2), (4, 4, 4), (6, 2, 3)]
    assert rec["operational_fitness"] == 4  # the best tested turn cycle (--operational tested)
    assert "coverage counts only" in res.output and rec["correction"] == "ga"
    assert rec["model_fitness"] == "coverage"
    assert (out / "runs.jsonl").read_text() == ""  # counts are not paths: nothing to diagnose
    figs = [o for o in read_jsonl(out / "observations.jsonl") if o["type"] == "figures"]
    assert [f["repeat_visits"] for f in figs] == [2, 0, 4] and figs[0]["repeat_visits_estimated"]


@pytest.mark.slow
def test_a_finished_run_carried_on_equals_a_longer_run(baseline, tmp_path):
    short = tmp_path / "short"
    assert invoke("evolve", "--out", str(short), "--generations", "20", *SMALL).exit_code == 0
    res = invoke("evolve", "--resume", str(short), "--generations", "40")
    assert res.exit_code == 0, res.output
    assert results(short) == results(baseline)


def test_emulator_options_are_refused_with_a_port(tmp_path):
    res = invoke("evolve", "--out", str(tmp_path / "o"), "--port", "/dev/null",
                 "--observer", "manual", "--sim-table", "measured")
    assert res.exit_code == 2 and "--sim-table describes the built-in emulator" in res.output


@pytest.mark.slow
def test_resume_keeps_the_emulated_world(tmp_path):
    """A run against an emulator with an unmodelled effect resumes against the same world."""
    out, whole = tmp_path / "cut", tmp_path / "whole"
    world = ["--sim-effect", "yaw_bias:delta=1.5", "--sim-noise", "0.3,0.5"]
    res = invoke("evolve", "--out", str(whole), "--generations", "20", *SMALL, *world)
    assert res.exit_code == 0, res.output
    res = invoke("evolve", "--out", str(out), "--generations", "20", *SMALL, *world,
                 "--mute-after", "450")
    assert res.exit_code == 1 and "stopped answering" in res.output
    assert invoke("evolve", "--resume", str(out)).exit_code == 0
    assert results(out) == results(whole)


@pytest.mark.slow
def test_path_fitness_brings_the_used_rows_to_the_robot(tmp_path):
    """With --model-fitness steps the model GA scores one-step residuals of the observed
    (noisy) paths, so the rows the tests use converge to the true robot's rows."""
    out = tmp_path / "steps"
    res = invoke("evolve", "--out", str(out), "--generations", "40", *SMALL,
                 "--model-fitness", "steps")
    assert res.exit_code == 0, res.output
    log = read_jsonl(out / "log.jsonl")
    assert all(r["model_fitness"] == "steps" for r in log)
    used = sorted({g for r in log for g in r["used_gait_ids"]})
    truth = shifted_table().rows[used]
    start = np.abs(load_table_rows("measured")[used] - truth).mean()
    end = np.abs(np.array(log[-1]["model"])[used] - truth).mean()
    assert end < 0.75 * start, (start, end)


def load_table_rows(name):
    from pac_host.model import resolve_table

    return resolve_table(name).rows


def test_resume_refuses_options_that_differ_from_the_saved_run(baseline, tmp_path):
    """`evolve --resume --seed 5` on a seed-4 run names --seed and changes nothing; options
    left out or the same are taken from the saved run, which a line lists."""
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(baseline, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    for args, words in ((["--seed", "5"], "--seed 5 differs from the saved run's 4; resume "
                                          "takes the saved options, drop --seed or start a "
                                          "new --out"),
                        (["--seed", "4", "--profile", "paper", "--sim-table", "measured"],
                         "drop --profile and --sim-table")):
        res = invoke("evolve", "--resume", str(out), *args)
        assert res.exit_code == 2, res.output
        lines = res.output.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], res.output
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    res = invoke("evolve", "--resume", str(out), "--seed", "4", "--placement-error", "0.5,1.0")
    assert res.exit_code == 0, res.output
    took = res.output.splitlines()[0]
    assert took.startswith("resuming with the saved options") and "--interval 20" in took
    assert "--seed" not in took and "--placement-error" not in took
    assert results(out) == results(baseline)
    res = invoke("evolve", "--resume", str(tmp_path / "missing"))
    assert res.exit_code == 2 and "no such directory" in res.output
