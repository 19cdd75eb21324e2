"""Helpers for the robot-link tests: run `pac-host` in-process and read its output files."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from pac_host.cli.main import main

# small GA settings so a punctuation takes about a second against the emulator at full speed
SMALL = ["--cga-population", "24", "--model-population", "12", "--model-generations", "15",
         "--initial-generations", "30", "--interval", "20", "--budget", "100", "--seed", "4",
         "--search-evaluations", "20000"]


def invoke(*args: str, input: str | None = None):
    return CliRunner().invoke(main, list(args), input=input)


def read_jsonl(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def results(out: Path) -> dict:
    """What a run decided: the punctuation records (minus wall-clock timing), the model, the
    operational turn cycle."""
    log = [{k: v for k, v in r.items() if k not in ("timing", "recovery")}
           for r in read_jsonl(out / "log.jsonl")]
    return {"log": log, "model": json.loads((out / "model.json").read_text()),
            "turn_cycle": json.loads((out / "turn_cycle.json").read_text())}


@pytest.fixture(scope="session")
def baseline(tmp_path_factory) -> Path:
    """One uninterrupted evolve run (3 punctuations), shared by the comparisons."""
    out = tmp_path_factory.mktemp("evolve") / "base"
    res = invoke("evolve", "--out", str(out), "--generations", "40", *SMALL)
    assert res.exit_code == 0, res.output
    return out


def evolve_against_pac_sim(out: Path, generations: int, *sim_args: str) -> str:
    """`pac-host evolve --port` against a separate `pac-sim` process (the real-robot path: the
    port, its tracker as observer and as placer); returns what pac-sim wrote to stderr."""
    proc = subprocess.Popen(
        [str(Path(sys.executable).parent / "pac-sim"), "--realtime", "0", "--tracker-noise",
         "0.5,1", *sim_args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = proc.stdout.readline().split()[-1]
        tracker = proc.stdout.readline().split()[-1]
        # a search that runs on while the robot walks would make the run depend on timing
        res = invoke("evolve", "--port", port, "--observer", f"tracker:{tracker}",
                     "--placer", "tracker", "--out", str(out), "--generations",
                     str(generations), "--no-search-while-walking", *SMALL)
        assert res.exit_code == 0, res.output
    finally:
        proc.send_signal(signal.SIGTERM)  # SIGINT is ignored under a background shell
        proc.wait(timeout=10)
    return proc.stderr.read()
