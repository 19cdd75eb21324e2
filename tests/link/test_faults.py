"""Faults at the link's edge cost one line and nothing else: a serial port that vanishes
mid-run, a robot that falls silent (given up at the time the docs state), and a bad input file
(refused before a port is opened or a folder made)."""

from __future__ import annotations

import os
import re
import select
import threading
import tty
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from pac_host.errors import PacError
from pac_host.model import load_table
from pac_host.robot.api import EVENT_TIMEOUT_S, StampRobot
from pac_host.robot.recovery import SILENT_READY_WAITS, give_up_s, with_redos
from pac_protocol.errors import PortVanished
from pac_protocol.link import READY_TIMEOUT_S, StampLink
from pac_protocol.port import open_port
from pac_sim.runner import SimConfig, SimStamp

from .conftest import SMALL, invoke, read_jsonl, results

ROOT = Path(__file__).resolve().parents[2]


class Relay:
    """A cable between the host and an emulated Stamp: a pseudo-terminal (:attr:`path`, the
    host's --port) whose other end copies bytes both ways to the emulator's port, until
    ``pull()`` is true; then it is closed, as if its USB adapter were pulled out."""

    def __init__(self, target: str, pull: Callable[[], bool]) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self._target = os.open(target, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self._target)
        for fd in (self.master, self._target):
            os.set_blocking(fd, False)
        self._pull = pull
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._copy, daemon=True)
        self._thread.start()

    def _copy(self) -> None:
        peer = {self.master: self._target, self._target: self.master}
        while not (self._pull() or self._stop.is_set()):
            ready, _, _ = select.select(list(peer), [], [], 0.005)
            for fd in ready:
                try:
                    os.write(peer[fd], os.read(fd, 4096))
                except (BlockingIOError, InterruptedError):
                    pass  # a full buffer: the bytes fall on the floor, as the emulator's do
        os.close(self.master)  # the host's side of the cable is gone
        os.close(self._slave)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        os.close(self._target)


def emulator() -> SimStamp:
    """The built-in emulator's world (shifted table, tracker noise 0.5 cm / 1 deg), on its own
    port and tracker, as `pac-sim` serves a real-robot command."""
    return SimStamp(SimConfig(factor=0.0, tracker=("127.0.0.1", 0),
                              tracker_noise=(0.5, 1.0))).start()


def evolve_on(port: str, sim: SimStamp, *args: str):
    host, tport = sim.tracker.address
    return invoke("evolve", "--port", port, "--observer", f"tracker:{host}:{tport}",
                  "--placer", "tracker", *args)


def test_a_vanished_port_is_one_typed_error_naming_it():
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    port = open_port(path)
    try:
        os.close(master)
        for touch in (lambda: port.in_waiting, lambda: port.read(1), lambda: port.write(b"x")):
            with pytest.raises(PortVanished, match=rf"the serial port {path} vanished \("):
                touch()
    finally:
        port.close()  # a vanished port closes quietly
        os.close(slave)


def test_a_pulled_cable_is_one_line_then_the_run_resumes_on_a_new_port(baseline, tmp_path):
    """The port vanishes after the first punctuation (a relay pty closed): one line naming
    the port, exit 1, the resume hint; resumed on a fresh port and a freshly powered robot, the
    run ends as the uninterrupted one's first two punctuations."""
    out = tmp_path / "cut"
    sim = emulator()
    relay = Relay(sim.path, lambda: (out / "state.json").exists())
    try:
        res = evolve_on(relay.path, sim, "--out", str(out), "--generations", "20", *SMALL,
                        "--no-search-while-walking", "--quiet")
    finally:
        relay.close()
        sim.close()
    assert res.exit_code == 1, res.output
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in res.output, res.output
    assert err[0].startswith("pac-host: error: run g20-t")
    assert f"the serial port {relay.path} vanished (" in err[0]
    assert f"`pac-host evolve --resume {out}`" in err[0]
    assert [r["generation"] for r in read_jsonl(out / "log.jsonl")] == [0]

    sim = emulator()
    try:
        res = evolve_on(sim.path, sim, "--resume", str(out))
    finally:
        sim.close()
    assert res.exit_code == 0, res.output
    base, got = results(baseline), results(out)
    for r in base["log"]:  # the built-in emulator's log also compares with its true table
        del r["true_error_on_used"]
    assert got["log"] == base["log"][:2]
    assert np.allclose(load_table(out / "model.json").rows, base["log"][1]["model"], atol=1e-6)
    assert got["turn_cycle"]["turn_cycle"] == base["log"][1]["operational"]

    def strip(runs: list[dict]) -> list[dict]:  # the robot was powered on again for the resume
        return [{k: v for k, v in r.items() if k != "cycles_since_power_on"} for r in runs]

    assert strip(read_jsonl(out / "runs.jsonl")) == strip(read_jsonl(baseline / "runs.jsonl")[:6])


def test_the_docs_state_the_give_up_time_of_the_code():
    """The give-up time of a silent robot: one definition (recovery.give_up_s), stated in
    the docs as its value and, in the how-to, as its terms."""
    bound = give_up_s()
    for doc in ("docs/how-to/real-robot.md", "docs/results.md"):
        text = " ".join((ROOT / doc).read_text().split())
        stated = re.findall(r"given up (\d+(?:\.\d+)?) s after", text)
        assert stated and {float(s) for s in stated} == {bound}, (doc, stated)
    text = " ".join((ROOT / "docs/how-to/real-robot.md").read_text().split())
    terms = re.search(r"the event timeout \((\S+) s\), then a READY timeout \((\S+) s\) for "
                      r"each of the (\w+) requests", text)
    assert terms is not None
    words = {"two": 2, "three": 3, "four": 4}
    assert (float(terms[1]), float(terms[2]), words[terms[3]]) == (
        EVENT_TIMEOUT_S, READY_TIMEOUT_S, SILENT_READY_WAITS)


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class SilentPort:
    """A port on which nothing ever arrives: each read waits out its timeout on the clock."""

    def __init__(self, clock: Clock) -> None:
        self.clock, self.timeout, self.written = clock, 0.05, []

    def read(self, size: int = 1) -> bytes:
        self.clock.t += self.timeout
        return b""

    @property
    def in_waiting(self) -> int:
        return 0

    def write(self, data: bytes) -> int:
        self.written.append(bytes(data))
        return len(data)


def test_a_silent_robot_is_given_up_at_the_stated_time():
    """Mid-run, the robot's last byte at t = 0 and its report handled until t = 1 (a slow
    observer): the run's silence, STATUS, the redo's STOP and STATUS, each waited for once on
    the dead line, and the error at exactly give_up_s() after the last byte (a fake clock)."""
    clock = Clock()
    port = SilentPort(clock)
    robot = StampRobot(StampLink(port, name="fake", clock=clock), EVENT_TIMEOUT_S)
    clock.t = 1.0
    redos: list[dict] = []
    with pytest.raises(PacError, match="stopped answering during a run of 10 gait cycles.*"
                                       "redoing the test"):
        with_redos(robot, lambda k: robot.follow(10, 0), redos.append)
    # (each wait may end up to one shortest read, 1 ms, past its deadline)
    assert give_up_s() <= clock.t < give_up_s() + 0.01
    assert robot.link.stats.requests == SILENT_READY_WAITS  # STATUS, STOP, STATUS
    assert robot.link.stats.retries == 0 and port.written == []  # nothing sent, none retried
    assert [r["type"] for r in redos] == ["redo"]


def test_a_robot_muted_before_anything_is_saved_is_not_offered_a_resume(tmp_path):
    out = tmp_path / "first"
    res = invoke("evolve", "--out", str(out), "--generations", "20", *SMALL,
                 "--mute-after", "5", "--quiet")
    assert res.exit_code == 1, res.output
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and "stopped answering" in err[0] and "Traceback" not in res.output
    assert "--resume" not in err[0] and "no punctuation is complete yet" in err[0]
    assert not (out / "state.json").exists()


@pytest.mark.parametrize("content", [b"{not json", b"\xff\xfe\x00bad", b'{"format": 1}'],
                         ids=["not-json", "not-utf8", "wrong-shape"])
def test_a_bad_model_is_refused_before_a_port_or_a_folder(tmp_path, content):
    model = tmp_path / "bad.json"
    model.write_bytes(content)
    out = tmp_path / "out"
    for port in (["--port", str(tmp_path / "no-such-port"), "--observer", "manual"], []):
        res = invoke("evolve", "--out", str(out), "--model", str(model), *port)
        assert res.exit_code == 2, res.output
        err = res.stderr.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"pac-host: error: --model: {model}")
        assert "port" not in err[0] and not out.exists()
