"""The observed-runs file: round trip, and one clear line for each kind of bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pac_host.diagnose.runs import Run, parse_runs, read_runs, write_runs
from pac_host.errors import InputError


def _run(**over) -> dict:
    doc = {"run_id": "r1", "start_pose": [45, 30, 90], "gait_cycles": [12, 12, 3],
           "poses": [[57, 30, 90], [69, 30, 90], [74, 26, 109]], "cycles_since_power_on": 5}
    doc.update(over)
    return doc


def test_round_trip(tmp_path):
    runs = parse_runs([json.dumps(_run()), "", json.dumps(_run(run_id="r2"))])
    assert [r.run_id for r in runs] == ["r1", "r2"]
    assert runs[0].cycles_since_power_on == 5
    assert runs[0].all_poses().shape == (4, 3)
    p = tmp_path / "runs.jsonl"
    write_runs(runs, p)
    back = read_runs(p)
    assert back[1].run_id == "r2"
    np.testing.assert_array_equal(back[0].poses, runs[0].poses)
    np.testing.assert_array_equal(back[0].gait_cycles, [12, 12, 3])


@pytest.mark.parametrize(
    "doc, words",
    [
        (_run(poses=[[57, 30, 90]]), ["line 1", "run 'r1'", "poses has 1", "gait_cycles has 3"]),
        (_run(gait_cycles=[12, 40, 3]), ["run 'r1'", "gait_cycles[1]", "40"]),
        (_run(start_pose=[45, 30]), ["run 'r1'", "start_pose"]),
        (_run(run_id=""), ["line 1", "run_id"]),
        (_run(cycles_since_power_on=-1), ["run 'r1'", "cycles_since_power_on"]),
        (_run(gait_cycles=[]), ["run 'r1'", "gait_cycles"]),
    ],
)
def test_bad_runs_name_run_and_field(doc, words):
    with pytest.raises(InputError) as e:
        parse_runs([json.dumps(doc)], "runs.jsonl")
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg


def test_nan_pose_named():
    line = json.dumps(_run()).replace("[69, 30, 90]", "[69, NaN, 90]")
    with pytest.raises(InputError, match=r"line 1.*NaN"):
        parse_runs([line], "runs.jsonl")
    line = json.dumps(_run()).replace("[69, 30, 90]", '[69, "x", 90]')
    with pytest.raises(InputError, match=r"run 'r1'.*poses\[1\]"):
        parse_runs([line], "runs.jsonl")


def test_not_json_lines_and_duplicates():
    with pytest.raises(InputError, match="line 2: not a JSON Lines record"):
        parse_runs([json.dumps(_run()), "{not json"], "runs.jsonl")
    with pytest.raises(InputError, match="line 2: run_id 'r1' already used on line 1"):
        parse_runs([json.dumps(_run()), json.dumps(_run())], "runs.jsonl")
    with pytest.raises(InputError, match="no runs"):
        parse_runs(["", "  "], "runs.jsonl")


def test_run_to_json_is_the_file_format():
    r = Run("a", np.zeros(3), np.array([1, 2]), np.ones((2, 3)), 3)
    assert parse_runs([json.dumps(r.to_json())])[0].to_json() == r.to_json()
