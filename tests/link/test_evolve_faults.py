"""`pac-host evolve` on a disk that fills up: one line and exit 1 saying how to go on, the
files written before whole, and a resumed run's results those of a run that never stopped."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from pac_host.model import load_table
from tests.host.test_faults_disk import disk_full, one_line

from .conftest import SMALL, invoke, read_jsonl, results


def test_a_full_disk_costs_nothing_but_the_punctuation_it_hit(baseline, tmp_path, monkeypatch):
    """The disk fills as the first punctuation's state is written: nothing of it is logged and
    the run is started again. Then it fills while the first punctuation's runs are appended
    after its state (it is complete: nothing is lost); a crash's torn line at the end of
    runs.jsonl is ignored too. Resumed, the run ends as the uninterrupted one's first two
    punctuations."""
    out = tmp_path / "full"
    run = ["--out", str(out), "--generations", "20", *SMALL, "--quiet"]
    with monkeypatch.context() as m:
        disk_full(m, "state.json")
        one_line(invoke("evolve", *run), 1,
                 f"{out / 'state.json'}: cannot write (No space left on device)",
                 f"no punctuation is complete yet: run the same command again (--out {out})")
    assert not (out / "state.json").exists() and not list(out.glob("*.tmp"))
    assert not (out / "log.jsonl").exists() and (out / "runs.jsonl").read_text() == ""

    with monkeypatch.context() as m:
        disk_full(m, "runs.jsonl", nth=2)  # the first opening creates the empty file
        one_line(invoke("evolve", *run), 1,
                 f"{out / 'runs.jsonl'}: cannot write (No space left on device)",
                 f"`pac-host evolve --resume {out}` continues from the last complete punctuation")
    assert (out / "runs.jsonl").read_text() == ""  # no half line
    assert not (out / "log.jsonl").exists()
    assert json.loads((out / "state.json").read_text())["generation"] == 0
    (out / "runs.jsonl").write_text('{"run_id": "g0-t0", "start_po')  # as a crash leaves it

    res = invoke("evolve", "--resume", str(out), "--quiet")
    assert res.exit_code == 0, res.output
    base = results(baseline)
    got = results(out)
    assert got["log"] == base["log"][:2]
    assert np.allclose(load_table(out / "model.json").rows, base["log"][1]["model"], atol=1e-6)
    assert got["turn_cycle"]["turn_cycle"] == base["log"][1]["operational"]
    runs, whole = read_jsonl(out / "runs.jsonl"), read_jsonl(baseline / "runs.jsonl")[:6]
    strip = [{k: v for k, v in r.items() if k != "cycles_since_power_on"} for r in runs]
    assert strip == [{k: v for k, v in r.items() if k != "cycles_since_power_on"} for r in whole]


@pytest.mark.parametrize("name", ["config.json", "state.json", "log.jsonl", "runs.jsonl"])
def test_undecodable_bytes_in_a_resumed_run_are_one_line(baseline, tmp_path, name):
    """What `evolve --resume` reads back, not UTF-8: one line naming the file (exit 2), and
    the run's files as they were."""
    out = tmp_path / "bad"
    shutil.copytree(baseline, out)
    (out / name).write_bytes((out / name).read_bytes()[:40] + b"\xff\xfe\n")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    line = one_line(invoke("evolve", "--resume", str(out), "--quiet"), 2, str(out / name))
    assert "not UTF-8" in line or "utf-8" in line, line
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
