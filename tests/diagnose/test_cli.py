"""`pac-host diagnose` end to end, as a user runs it, and its bad-input errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pac_host.diagnose.runs import write_runs
from pac_host.model import Effect, load_table


def _cli(*args, cwd=None):
    exe = Path(sys.executable).parent / "pac-host"  # the installed entry point
    return subprocess.run([str(exe), *args], capture_output=True, text=True, cwd=cwd)


@pytest.fixture(scope="module")
def runs_file(tmp_path_factory, cycles):
    from pac_host.diagnose.synth import world_runs
    from pac_host.model import measured_table

    rng = np.random.default_rng(21)
    runs = world_runs(measured_table().rows, [Effect("yaw_bias", {"delta": -0.8})], cycles[:30],
                      50, rng)
    p = tmp_path_factory.mktemp("diag") / "runs.jsonl"
    write_runs(runs, p)
    return p


def test_diagnose_end_to_end(runs_file, tmp_path):
    report, plots, model = tmp_path / "r.json", tmp_path / "plots", tmp_path / "m.json"
    r = _cli("diagnose", "--model", "measured", "--runs", str(runs_file), "--seed", "3",
             "--json", str(report), "--plots", str(plots), "--write-model", str(model))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("verdict: explained")
    assert "yaw_bias: delta=-0.8" in r.stdout
    doc = json.loads(report.read_text())
    assert doc["format"] == "pac-diagnosis/1"
    for key in ("noise_floor", "where", "candidates", "selected", "verdict", "holdout"):
        assert key in doc
    assert set(doc["noise_floor"]) >= {"pos_cm", "heading_deg"}
    assert set(doc["where"]) >= {"by_gait_cycle", "by_component", "by_context",
                                 "rollout_end_cm", "coverage"}
    assert len(doc["where"]["rollout_end_cm"]["per_run"]) == 30
    assert doc["where"]["rollout_end_cm"]["max"] > 10  # a 0.8 deg/cycle yaw bias drifts far
    row = doc["where"]["by_gait_cycle"][0]
    assert set(row) >= {"id", "n", "mean", "rms"} and len(row["mean"]) == 3
    c = doc["candidates"][0]
    assert c["effect"] == "yaw_bias"
    assert set(c) >= {"effect", "params", "fit", "holdout", "p_value", "delta_bic"}
    assert set(c["holdout"]) >= {"step_rms_before", "step_rms_after", "rollout_cm_before",
                                 "rollout_cm_after", "shrink"}
    assert doc["selected"] == ["yaw_bias"]
    assert doc["informative"] is True
    h = doc["holdout"]
    assert h["runs"] == 9 and h["shrink"] > 0.8
    assert h["shrink_ci"][0] <= h["shrink"] <= h["shrink_ci"][1]
    assert len(doc["runs"]["held_out"]) == 9
    assert not set(doc["runs"]["held_out"]) & set(doc["runs"]["fitting"])
    pngs = sorted(plots.glob("*.png"))
    assert len(pngs) == 4
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    table = load_table(model)
    assert [e.name for e in table.effects] == ["yaw_bias"]
    assert table.effects[0].params["delta"] == pytest.approx(-0.8, abs=0.05)
    sim = _cli("simulate", "--table", str(model), "--turn-cycle", "12:10", "--budget", "5",
               "--json")
    assert sim.returncode == 0, sim.stderr
    poses = json.loads(sim.stdout)["poses"]
    assert poses[1][2] == pytest.approx(90 + table.effects[0].params["delta"])


def test_same_seed_same_report(runs_file, tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    for p in (a, b):
        assert _cli("diagnose", "--model", "measured", "--runs", str(runs_file), "--seed", "5",
                    "--json", str(p)).returncode == 0
    assert json.loads(a.read_text()) == json.loads(b.read_text())


def test_holdout_file_and_library(runs_file, tmp_path):
    lines = runs_file.read_text().splitlines()
    fit, hold = tmp_path / "fit.jsonl", tmp_path / "hold.jsonl"
    fit.write_text("\n".join(lines[:20]) + "\n")
    hold.write_text("\n".join(lines[20:]) + "\n")
    report = tmp_path / "r.json"
    r = _cli("diagnose", "--model", "measured", "--runs", str(fit), "--holdout", str(hold),
             "--library", "turn_scale,stride_scale", "--json", str(report))
    assert r.returncode == 0, r.stderr
    doc = json.loads(report.read_text())
    assert doc["holdout"]["runs"] == 10
    assert {c["effect"] for c in doc["candidates"]} == {"turn_scale", "stride_scale"}
    assert doc["verdict"] == "partly_unexplained"  # the yaw bias is not in this library
    assert "what remains unexplained" in r.stdout
    remaining = doc["holdout"]["where_remaining"]["by_gait_cycle"]
    assert any(abs(m) > 4 * se for row in remaining  # a clear residual is left somewhere
               for m, se in zip(row["mean"], row["se"], strict=True))


@pytest.mark.parametrize("content, words", [
    ('{"run_id": "a", "start_pose": [0, 0, 0], "gait_cycles": [1, 2], "poses": [[0, 0, 0]]}',
     ["run 'a'", "poses has 1"]),
    ('{"run_id": "b", "start_pose": [0, 0, 0], "gait_cycles": [33], "poses": [[0, 0, 0]]}',
     ["run 'b'", "gait_cycles[0]"]),
    ('{"run_id": "c", "start_pose": [0, 0, 0], "gait_cycles": [3], "poses": [[0, NaN, 0]]}',
     ["line 1", "NaN"]),
    ("hello", ["line 1", "not a JSON Lines record"]),
    ('{"run_id": "d", "start_pose": [0, 0, 0], "gait_cycles": [3], "poses": [[0, 1, 0]]}',
     ["too few runs to hold any out"]),
])
def test_bad_input_one_line_exit_2(tmp_path, content, words):
    p = tmp_path / "bad.jsonl"
    p.write_text(content + "\n")
    out = tmp_path / "r.json"
    r = _cli("diagnose", "--model", "measured", "--runs", str(p), "--json", str(out))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pac-host: error: ")
    for w in words:
        assert w in lines[0]
    assert not out.exists()


def test_bad_holdout_fraction(runs_file):
    r = _cli("diagnose", "--model", "measured", "--runs", str(runs_file),
             "--holdout-fraction", "1.5")
    assert r.returncode == 2
    assert r.stderr.strip() == ("pac-host: error: --holdout-fraction must be between 0 and 1, "
                                "got 1.5")


def test_holdout_file_and_fraction_exclude_each_other(runs_file):
    r = _cli("diagnose", "--model", "measured", "--runs", str(runs_file), "--holdout",
             str(runs_file), "--holdout-fraction", "0.2")
    assert r.returncode == 2
    assert r.stderr.strip() == "pac-host: error: give --holdout or --holdout-fraction, not both"
