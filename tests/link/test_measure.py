"""`pac-host measure` rebuilds the emulator's true table from noisy tracker observations."""

from __future__ import annotations

import json

import numpy as np

from pac_host.model import load_table, measured_table, shifted_table

from .conftest import invoke, read_jsonl


def test_measure_recovers_the_true_table_within_3_standard_errors(tmp_path):
    out = tmp_path / "table.json"
    res = invoke("measure", "--out", str(out), "--repeats", "10", "--sim-table", "shifted",
                 "--sim-noise", "0.5,1", "--table", "measured", "--seed", "2")
    assert res.exit_code == 0, res.output
    table = load_table(out)
    doc = json.loads(out.with_name("table.measure.json").read_text())
    truth = shifted_table().rows
    se = np.array([[f["se_F"], f["se_T"], f["se_dH"]] for f in doc["fits"]])
    assert [f["id"] for f in doc["fits"]] == list(range(32))
    z = (table.rows - truth) / se
    assert np.abs(z).max() < 3, np.abs(z).max()  # every id and component within 3 SE
    # the standard errors are honest: neither inflated (z would shrink) nor too small
    assert 0.7 < z.std() < 1.4, z.std()
    assert (se > 0.05).all() and (se < 1.0).all()
    # and the change from the current (measured) table is found where it is large
    moved = np.abs(shifted_table().rows - measured_table().rows)[:, 2] > 2.0
    flagged = np.array([abs(d["z_dH"]) > 3 for d in doc["differences"]])
    assert flagged[moved].mean() > 0.8
    assert f"ids differ from measured by more than 3 standard errors; wrote {out}" in res.output
    assert out.with_name("table.png").read_bytes()[:4] == b"\x89PNG"
    runs = read_jsonl(out.with_name("table.runs.jsonl"))
    assert len(runs) == 320 and runs[0]["gait_cycles"] == [0]


def test_measure_by_hand_asks_again_for_a_non_number(tmp_path):
    out = tmp_path / "hand.json"
    # two placements of gait 12; the first answer is not a number and is asked again
    replies = "ninety 100 0\n90.1 102.0 0.5\n89.9 102.2 -0.5\n"
    res = invoke("measure", "--out", str(out), "--ids", "12", "--repeats", "2",
                 "--observer", "manual", "--sim-noise", "0,0", input=replies)
    assert res.exit_code == 0, res.output
    assert "'ninety 100 0' is not 3 numbers" in res.output
    row = load_table(out).rows[12]
    assert np.allclose(row, [12.1, 0.0, 0.0], atol=1e-9)  # from (90, 90, 0): F 12.1, T 0, dH 0
    assert load_table(out).rows[13].tolist() == measured_table().rows[13].tolist()


def test_measure_bad_input(tmp_path):
    for args, words in ((["--ids", "5-40"], "within 0..31"), (["--repeats", "1"], "--repeats"),
                        (["--ids", "x"], "--ids"), (["--start", "1,2"], "--start")):
        res = invoke("measure", "--out", str(tmp_path / "t.json"), *args)
        assert res.exit_code == 2 and words in res.output, res.output
