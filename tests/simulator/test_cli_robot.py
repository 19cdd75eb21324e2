"""`pac-sim` as a real process and `pac-host robot` against it; bad input is one clear line."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_sim.line import Faults

BIN = Path(sys.executable).parent


def robot(*args: str):
    return CliRunner().invoke(main, ["robot", *args])


def one_error_line(res, code: int, words: str) -> None:
    assert res.exit_code == code, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pac-host: error:"), res.output
    assert words in lines[0] and "Traceback" not in res.output


@pytest.fixture
def pac_sim(tmp_path, backend, firmware_source):
    firmware = ["--firmware", firmware_source] if backend == "firmware" else []
    proc = subprocess.Popen(
        [str(BIN / "pac-sim"), "--realtime", "0", "--eeprom", str(tmp_path / "e.json"), *firmware],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    first = proc.stdout.readline()
    tracker = proc.stdout.readline()
    assert first.startswith("pac-sim: stamp on /dev/") and "tracker on 127.0.0.1:" in tracker
    yield proc, first.split()[-1]
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        proc.wait(timeout=10)


def test_robot_commands_against_the_pac_sim_process(pac_sim, tmp_path):
    proc, port = pac_sim
    res = robot("hello", "--port", port)
    assert res.exit_code == 0 and "protocol 1, firmware 1, up to 9 genes" in res.output
    assert robot("load", "12:2,3:1", "--port", port).output.strip() == "stored 2 genes"
    res = robot("run", "4", "--port", port)
    assert res.exit_code == 0, res.output
    lines = res.output.strip().splitlines()
    assert [ln.split(": gait ")[1].split()[0] for ln in lines[:4]] == ["12", "12", "3", "12"]
    assert lines[-1] == "done: completed after 4 gait cycles"
    res = robot("step", "7", "2", "--port", port)
    assert res.output.strip().splitlines()[-1] == "done: completed after 2 gait cycles"
    assert robot("stop", "--port", port).output.strip() == "stop acknowledged"
    res = robot("status", "--port", port)
    assert res.output.strip() == (
        "state idle, gait cycles done 2, since power-on 6, turn cycle 12:2,3:1"
    )
    os.kill(proc.pid, signal.SIGTERM)
    assert proc.wait(timeout=10) == 0
    assert "stopped after 6 gait cycles" in proc.stderr.read()
    assert '"turn_cycle": [[12, 2], [3, 1]]' in (tmp_path / "e.json").read_text()


@pytest.mark.parametrize(
    "port, words",
    [("/nonexistent/ttyUSB9", "does not exist"), ("/dev/null", "not a serial device")],
)
def test_bad_port_exits_2(port, words):
    one_error_line(robot("hello", "--port", port), 2, words)


def test_silent_device_exits_1(make_sim):
    sim, _ = make_sim(faults=Faults(silent=True))
    one_error_line(robot("hello", "--port", sim.path, "--timeout", "0.3"), 1, sim.path)


def test_version_mismatch_exits_1(make_sim):
    sim, _ = make_sim(protocol_version=3)
    res = robot("status", "--port", sim.path)
    one_error_line(res, 1, "expected protocol version 1, the Stamp speaks version 3")
    assert sim.path in res.output


@pytest.mark.parametrize(
    "args, words",
    [
        (["step", "40", "1"], "gait id must be 0..31"),
        (["step", "3", "0"], "repetitions must be 1..65535"),
        (["load", "12:64"], "repetitions 64"),
        (["load", "12"], "expected GAIT:REPS"),
        (["run", "0"], "gait cycles must be 1..65535"),
    ],
)
def test_bad_arguments_exit_2_before_touching_the_port(args, words):
    one_error_line(robot(*args, "--port", "/nonexistent"), 2, words)


@pytest.mark.parametrize(
    "args, words",
    [
        (["--realtime", "-1"], "--realtime must be >= 0"),
        (["--tracker", "nowhere"], "expected HOST:PORT"),
        (["--drop-prob", "2"], "--drop-prob must be in [0, 1]"),
        (["--start", "1,2"], "--start: expected 3"),
        (["--effect", "nope:x=1"], "unknown effect"),
        (["--firmware", "/nonexistent/fw.bs2"], "/nonexistent/fw.bs2: cannot read"),
        (["--image", "servobot.json"], "give --firmware SOURCE too"),
        (["--step-noise", "-0.3,1"], "deviations must be >= 0"),
        (["--step-noise", "0.3"], "--step-noise takes CM,DEG"),
    ],
)
def test_pac_sim_bad_options_are_one_line(args, words):
    res = subprocess.run([str(BIN / "pac-sim"), *args], capture_output=True, text=True, timeout=30)
    assert res.returncode == 2 and res.stdout == ""
    assert res.stderr.count("\n") == 1 and words in res.stderr and "Traceback" not in res.stderr
