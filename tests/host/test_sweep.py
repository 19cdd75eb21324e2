"""`pac-host sweep` and the executors: settings, the same results on any engine, faults, resume."""

from __future__ import annotations

import json
import os
import shutil
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.errors import InputError
from pac_host.experiments.sweep import load_sweep, parse_sweep, run_sweep
from pac_host.experiments.sweep.settings import canonical_name, experiment_config, setting_names

TINY = """
[settings]
seeds = 2
generations = 40
initial_generations = 10
optimum_runs = 1
optimum_generations = 20
cga_population = 16
model_population = 8
model_generations = 10
budget = 80

[grid]
methods = ["full", "partial"]
model_fitness = ["coverage", "steps"]

[[cells]]
methods = "oracle"
effects = ["yaw_bias:delta=1.5"]
"""
N_ROWS = 5 * 2  # (2 x 2 grid cells + 1 explicit cell) x 2 seeds, one method each


def _run(args):
    return CliRunner().invoke(main, args, catch_exceptions=False)


def _outputs(out: Path) -> dict[str, bytes]:
    """Every result file of a sweep but the logs, whose lines land in completion order."""
    files = [out / "results.json", out / "results.csv", *sorted(out.glob("cells/*/summary.json")),
             *sorted(out.glob("cells/*/optimum.json"))]
    return {str(p.relative_to(out)): p.read_bytes() for p in files}


def _sorted_logs(out: Path) -> dict[str, list[str]]:
    return {p.parent.name: sorted(p.read_text().splitlines())
            for p in out.glob("cells/*/log.jsonl")}


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "sweep.toml"
    path.write_text(TINY)
    return path


@pytest.fixture(scope="module")
def serial(sweep_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    res = _run(["sweep", str(sweep_file), "--out", str(out), "--jobs", "1"])
    assert res.exit_code == 0, res.output
    return out, res.output


@pytest.fixture(scope="module")
def cluster():
    """One LocalCluster of 2 worker processes for the module (start-up costs seconds)."""
    import logging

    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.ERROR) as c, Client(c) as cl:
        yield c, cl


# -- settings: generic over the config's fields ----------------------------------------------

def test_settings_are_the_configs_fields_by_path_or_unambiguous_name():
    assert canonical_name("pal.budget") == canonical_name("budget") == "budget"
    assert canonical_name("model-fitness") == "model_fitness"
    assert canonical_name("pal.cga.bit_mutation_rate") == "bit_mutation_rate"
    assert canonical_name("pal.cga.elite") == "pal.cga.elite"  # elite is also the model GA's
    cfg = experiment_config({"profile": "paper", "budget": 50, "pal.cga.elite": 3,
                             "pal.model.elite": 2, "methods": ["full"],
                             "scale": [0.5, 0.5, 2.0]})
    assert (cfg.pal.budget, cfg.pal.cga.elite, cfg.pal.model.elite) == (50, 3, 2)
    assert cfg.methods == ("full",) and cfg.pal.model.scale == (0.5, 0.5, 2.0)
    for key, message in [("elite", "unknown setting 'elite'"),
                         ("budgett", "did you mean 'budget'"),
                         ("pal.method", "the experiment sets it; sweep 'methods'")]:
        with pytest.raises(InputError, match=message):
            canonical_name(key)


@dataclass(frozen=True)
class Inner:
    rate: float = 0.1
    budget: int = 5


@dataclass(frozen=True)
class Outer:
    budget: int = 1
    new_knob: int = 0
    inner: Inner = field(default_factory=Inner)


def test_a_field_added_to_a_config_is_a_setting_without_a_change():
    names = setting_names(Outer)
    assert names["new_knob"] == ("new_knob",) and names["rate"] == ("inner", "rate")
    assert names["budget"] == ("budget",)  # the shallowest wins
    assert names["inner.budget"] == ("inner", "budget")


def test_grid_cells_and_files(tmp_path):
    (tmp_path / "robots").mkdir()
    _run(["table", "export", str(tmp_path / "robots" / "r.json"), "--table", "measured"])
    doc = {"settings": {"profile": "paper", "seeds": 3, "pal": {"cga": {"elite": 4}}},
           "grid": {"methods": ["full", "partial"], "budget": [100, 150, 200],
                    "actual": ["shifted", "robots/r.json"]},
           "cells": [{"methods": "oracle"}, {"methods": "full", "budget": 100,
                                             "actual": "shifted"}]}  # the second repeats one
    cells = parse_sweep(doc, tmp_path)
    assert len(cells) == 2 * 3 * 2 + 1
    assert [c.index for c in cells] == list(range(len(cells)))
    assert all(c.config.seeds == 3 and c.config.pal.cga.elite == 4 for c in cells)
    assert {c.actual.name for c in cells} >= {"shifted", "r"}
    assert cells[-1].settings["methods"] == ["oracle"] and cells[-1].config.pal.budget == 200
    assert len({c.id for c in cells}) == len(cells)
    assert all(c.settings["profile"] == "paper" and c.config.pal.correction == "ga"
               and c.config.optimum_search == "cga" for c in cells)


def test_a_cell_records_its_profile_and_compares_methods_that_differ():
    """A cell's settings start from its profile (none: the configuration's own defaults), and
    unless it sets methods it compares those that differ under it: full only where a model GA
    runs."""
    cells = parse_sweep({"grid": {"profile": ["paper", "default", "none"]},
                         "cells": [{"model_generations": 10}]})
    got = {c.settings["profile"]: c.config for c in cells[:3]}
    assert got["paper"].methods == ("full", "partial", "oracle")
    assert got["default"].methods == got["none"].methods == ("partial", "oracle")
    assert got["default"].pal.search == "ils" and got["default"].optimum_search == "optimize"
    assert got["none"].pal.search == "cga" and got["none"].pal.correction == "fit"
    assert cells[3].settings == {"profile": "none", "model_generations": 10}
    assert cells[3].config.methods == ("full", "partial", "oracle")


# -- the same results whatever runs it --------------------------------------------------------

def test_sweep_writes_a_row_per_cell_seed_and_method(serial):
    out, text = serial
    doc = json.loads((out / "results.json").read_text())
    assert doc["format"] == "pac-sweep/1" and len(doc["cells"]) == 5
    assert len(doc["rows"]) == N_ROWS
    assert {(r["cell_index"], r["seed"]) for r in doc["rows"]} == {
        (i, s) for i in range(5) for s in (0, 1)}
    csv_lines = (out / "results.csv").read_text().splitlines()
    assert len(csv_lines) == N_ROWS + 1 and "model_fitness" in csv_lines[0]
    for r in doc["rows"]:
        summary = json.loads((out / "cells" / r["cell"] / "summary.json").read_text())
        run = next(x for x in summary["runs"] if x["seed"] == r["seed"])
        assert r["final_coverage"] == run["coverage"][-1] <= r["best_known"]
        assert r["best_known"] >= summary["optimum"]
    oracle = [r for r in doc["rows"] if r["method"] == "oracle"]
    assert oracle and all(r["effects"] == ["yaw_bias:delta=1.5"] for r in oracle)
    assert all(r["profile"] == "none" for r in doc["rows"]) and "profile" in csv_lines[0]
    for c in doc["cells"]:
        assert json.loads((out / "cells" / c["id"] / "cell.json").read_text())[
            "settings"]["profile"] == "none"
    for name in ("final_coverage.png", "mean_coverage.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"
    assert text.count(": done in") == 5 and "cells per minute" in text


def test_a_local_cluster_of_2_workers_gives_the_results_of_jobs_1(serial, sweep_file, tmp_path):
    out, _ = serial
    res = _run(["sweep", str(sweep_file), "--out", str(tmp_path), "--jobs", "2"])
    assert res.exit_code == 0, res.output
    assert _outputs(tmp_path) == _outputs(out)  # bit for bit
    assert _sorted_logs(tmp_path) == _sorted_logs(out)


def test_an_interrupted_sweep_resumes_to_the_same_results(serial, sweep_file, tmp_path):
    out, _ = serial
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    # as if killed mid-cell: one cell without its summary and with half its PAL runs logged
    cut = sorted((tmp_path / "cells").iterdir())[1]
    (cut / "summary.json").unlink()
    lines = (cut / "log.jsonl").read_text().splitlines()
    (cut / "log.jsonl").write_text("\n".join(lines[:4]) + "\n")
    (tmp_path / "results.json").unlink()
    res = _run(["sweep", str(sweep_file), "--out", str(tmp_path)])
    assert res.exit_code == 2 and "--resume" in res.output
    res = _run(["sweep", str(sweep_file), "--out", str(tmp_path), "--resume"])
    assert res.exit_code == 0, res.output
    assert res.output.count("already done") == 4 and res.output.count(": done in") == 1
    assert _outputs(tmp_path) == _outputs(out)
    assert _sorted_logs(tmp_path) == _sorted_logs(out)


def test_resume_refuses_a_folder_without_this_sweep_and_writes_nothing(serial, sweep_file,
                                                                       tmp_path):
    out, _ = serial
    empty, run = tmp_path / "empty", tmp_path / "run"
    empty.mkdir()
    shutil.copytree(out, run)
    other = tmp_path / "other.toml"
    other.write_text(TINY.replace("seeds = 2", "seeds = 3"))

    def files(d):
        return {str(p.relative_to(d)): p.read_bytes() for p in d.rglob("*") if p.is_file()}

    before = files(run)
    for args, words in (([str(sweep_file), "--out", str(tmp_path / "missing")],
                         "no such directory"),
                        ([str(sweep_file), "--out", str(empty)], "the directory is empty"),
                        ([str(sweep_file), "--out", str(run / "cells")],
                         "no sweep.json there (not a sweep run)"),
                        ([str(other), "--out", str(run)],
                         f"SWEEP.toml {other} differs from the saved run's")):
        res = _run(["sweep", *args, "--resume"])
        assert res.exit_code == 2, res.output
        lines = res.output.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], res.output
    assert not (tmp_path / "missing").exists() and not any(empty.iterdir())
    assert files(run) == before
    saved = json.loads((run / "sweep.json").read_text())
    assert saved["sweep_file"] == str(sweep_file.resolve()) and len(saved["cells"]) == 5


def test_experiment_on_a_dask_scheduler_matches_the_local_run(cluster, tmp_path):
    small = ["--seeds", "2", "--generations", "40", "--initial-generations", "10",
             "--optimum-runs", "1", "--optimum-generations", "20", "--methods", "partial",
             "--budget", "80", "--optimum-evaluations", "20000", "--search-evaluations", "5000"]
    res = _run(["experiment", *small, "--out", str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    res = _run(["experiment", *small, "--out", str(tmp_path / "b"),
                "--scheduler", cluster[0].scheduler_address])
    assert res.exit_code == 0, res.output
    for name in ("summary.json", "optimum.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    a, b = ((tmp_path / d / "log.jsonl").read_text().splitlines() for d in "ab")
    assert len(a) == 2 * 2 and sorted(a) == sorted(b)


def test_a_worker_killed_mid_sweep_loses_nothing(cluster, serial, sweep_file, tmp_path):
    """A worker process is killed while it holds tasks; the sweep still completes, with the
    results of --jobs 1."""
    from pac_host.experiments.executors import DaskExecutor

    out, _ = serial
    c, client = cluster
    pids = client.run(os.getpid)
    killed: list[int] = []
    stop = threading.Event()

    def killer():
        while not stop.is_set() and not killed:
            for addr, keys in client.processing().items():
                if keys and addr in pids:
                    os.kill(pids[addr], signal.SIGKILL)
                    killed.append(pids[addr])
                    return
            time.sleep(0.005)

    t = threading.Thread(target=killer)
    t.start()
    try:
        run_sweep(load_sweep(sweep_file), tmp_path, DaskExecutor(client))
    finally:
        stop.set()
        t.join()
    assert killed, "no worker was killed while running a task"
    assert killed[0] not in client.run(os.getpid).values()
    assert _outputs(tmp_path) == _outputs(out)
    assert _sorted_logs(tmp_path) == _sorted_logs(out)


# -- bad input: one line, exit 2 --------------------------------------------------------------

@pytest.mark.parametrize("text, extra, message", [
    ("[grid]\nmethods = ['full']\nbogus = [1]\n", [], "unknown setting 'bogus'"),
    ("[settings]\nseeds = 2\n[grid]\nmethods = []\n", [], "methods has no values"),
    ("[settings]\nseeds = 2\n", [], "no cells"),
    ("[grid]\nbudget = ['x']\n", [], "setting 'budget' must be an integer, got 'x'"),
    ("[grid]\nmethods = ['half']\n", [], "--methods takes full"),
    ("[grid]\nactual = ['nope.json']\n", [], "nope.json: cannot read"),
    ("[grid\n", [], "not valid TOML"),
    ("[grid]\nmethods = ['full', 'partial']\n", [],
     "cell 1: --methods full: full differs from partial only in the model GA's recombination"),
    ("[settings]\nprofile = 'fast'\n[grid]\nseeds = [1]\n", [],
     "setting 'profile' takes paper, default, none, got 'fast'"),
    ("[grid]\nmethods = ['partial']\n", ["--scheduler", "tcp://127.0.0.1:1",
                                         "--connect-timeout", "0.5"],
     "cannot reach the Dask scheduler at tcp://127.0.0.1:1"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, text, extra, message):
    (tmp_path / "s.toml").write_text(text)
    res = CliRunner().invoke(main, ["sweep", str(tmp_path / "s.toml"), "--out",
                                    str(tmp_path / "out"), *extra])
    assert res.exit_code == 2, res.output
    assert message in res.output
    assert "Traceback" not in res.output
    assert len(res.output.strip().splitlines()) == 1


def test_experiment_with_an_unreachable_scheduler_is_one_line_and_exit_2(tmp_path):
    res = CliRunner().invoke(main, ["experiment", "--out", str(tmp_path), "--scheduler",
                                    "tcp://127.0.0.1:1", "--connect-timeout", "0.5"])
    assert res.exit_code == 2, res.output
    assert res.output.startswith("pac-host: error: cannot reach the Dask scheduler")
    assert len(res.output.strip().splitlines()) == 1


def test_the_documented_example_sweep_is_valid():
    """It asks the paper's question where it has an answer: under the paper's profile, whose
    model GA the recombination acts in."""
    from pac_host.learning.config import recombination_inert

    cells = load_sweep(Path(__file__).resolve().parents[2] / "examples" / "sweep.toml")
    assert len(cells) == 2 * 2 * 3 + 3
    assert all(c.config.seeds == 30 for c in cells)
    assert all(c.settings["profile"] == "paper" for c in cells)
    assert not any(recombination_inert(c.config.pal) for c in cells)
    assert {c.config.methods for c in cells} == {("full",), ("partial",), ("oracle",)}
