"""`pac-host evolve --port` against `pac-sim --firmware`: the paper's loop with the firmware
itself walking the tests (its servo trace moving the emulated world), for two punctuations, on a
clean line and on one that drops and corrupts 1% of the bytes each way (the firmware's own
timing, not the protocol-level model's, is what the host's recovery must meet)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pac_host.coverage import START_POSE
from pac_host.model import rollout, shifted_table

from .conftest import SMALL, evolve_against_pac_sim, invoke, read_jsonl, results

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "servobot.bs2"


@pytest.fixture(scope="module")
def builtin(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("fw") / "builtin"
    res = invoke("evolve", "--out", str(out), "--generations", "20", *SMALL)
    assert res.exit_code == 0, res.output
    return out


@pytest.mark.slow
@pytest.mark.parametrize("line", [(), ("--drop-prob", "0.01", "--corrupt-prob", "0.01",
                                       "--seed", "5")], ids=["clean", "noisy"])
def test_evolve_against_the_firmware_in_the_loop(tmp_path, builtin, line):
    out = tmp_path / "firmware"
    stderr = evolve_against_pac_sim(out, 20, "--firmware", str(FIRMWARE), *line)
    assert "warning" not in stderr  # every gait cycle's thrust matched its row
    log = read_jsonl(out / "log.jsonl")
    assert [r["generation"] for r in log] == [0, 20]
    runs = read_jsonl(out / "runs.jsonl")
    assert len(runs) == 6 and all(len(r["gait_cycles"]) == 100 for r in runs)
    for run in runs:  # the firmware's servo trace walked the true table's rows (plus noise)
        true = rollout(shifted_table().rows, START_POSE, run["gait_cycles"])
        err = np.array(run["poses"]) - true[1:]
        assert np.abs(err[:, :2]).max() < 3.5 and np.abs(err[:, 2]).max() < 7
    # the same robot, the same seeds: the same decisions as with the protocol-level emulator
    base = results(builtin)
    for r in base["log"]:
        del r["true_error_on_used"]
    assert results(out) == base
    assert (out / "runs.jsonl").read_text() == (builtin / "runs.jsonl").read_text()
    if line:  # the noisy line really needed the recovery
        assert sum(r["recovery"]["retries"] for r in log) > 0
