"""Across the parts: runs observed by `evolve` on the emulator feed `diagnose`, which names the
robot's unmodelled effect; the corrected model it writes is what `evolve --model` trains on."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.model import load_table

SMALL = ["--cga-population", "24", "--model-population", "12", "--model-generations", "10",
         "--initial-generations", "30", "--interval", "20", "--budget", "100", "--seed", "2",
         "--search-evaluations", "20000"]


def _invoke(*args):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


@pytest.mark.slow
def test_evolve_runs_diagnose_then_evolve_on_the_corrected_model(tmp_path):
    first = tmp_path / "evolve"
    res = _invoke("evolve", "--out", str(first), "--generations", "60", *SMALL,
                  "--sim-table", "shifted", "--sim-effect", "yaw_bias:delta=1.2")
    assert res.exit_code == 0, res.output
    runs = (first / "runs.jsonl").read_text().splitlines()
    assert len(runs) == 12

    report, corrected = tmp_path / "report.json", tmp_path / "corrected.json"
    res = _invoke("diagnose", "--model", "shifted", "--runs", str(first / "runs.jsonl"),
                  "--seed", "1", "--json", str(report), "--write-model", str(corrected))
    assert res.exit_code == 0, res.output
    doc = json.loads(report.read_text())
    assert doc["format"] == "pac-diagnosis/1"
    assert doc["selected"][:1] == ["yaw_bias"], doc["selected"]
    table = load_table(corrected)
    (bias,) = [e for e in table.effects if e.name == "yaw_bias"]
    assert abs(bias.params["delta"] - 1.2) < 0.2

    # the paper's model GA keeps the model's effects as they are (the default whole-table
    # correction refits them and folds table-level ones into the rows)
    second = tmp_path / "evolve2"
    res = _invoke("evolve", "--out", str(second), "--generations", "20", *SMALL,
                  "--model", str(corrected), "--sim-effect", "yaw_bias:delta=1.2",
                  "--correction", "ga", "--tests", "paper", "--operational", "best")
    assert res.exit_code == 0, res.output
    kept = load_table(second / "model.json").effects
    assert [e.name for e in kept] == [e.name for e in table.effects]
