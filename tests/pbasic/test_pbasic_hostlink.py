"""A Stamp served on a real pseudo-terminal, talked to with pyserial: the host gets what the
program SEROUTs, its bytes reach a waiting SERIN, and bytes sent while the program is busy
are lost, in paced Stamp time."""

from __future__ import annotations

import os
import threading
import tty
from pathlib import Path

import pytest
import serial

from pac_sim.pbasic import Stamp
from pac_sim.pbasic.hostlink import FdLink, serve

HEADER = "' {$STAMP BS2}\n' {$PBASIC 2.5}\n"
BUSY_THEN_LISTEN = HEADER + (
    "x VAR Byte\n"
    "SEROUT 16, 16468, [\"A\"]\n"
    "PAUSE 600\n"
    "SEROUT 16, 16468, [\"B\"]\n"
    "SERIN 16, 16468, 1500, Quiet, [x]\n"
    "SEROUT 16, 16468, [\"got\", x]\n"
    "END\n"
    "Quiet:\n"
    "  SEROUT 16, 16468, [\"T\"]\n"
    "  END\n"
)


@pytest.fixture
def served():
    """Start serve() on a fresh pty; yields (stamp-starter, pyserial port)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    port = serial.Serial(os.ttyname(slave), 9600, timeout=5)
    stop = threading.Event()
    threads: list[threading.Thread] = []

    def start(stamp: Stamp, **kw) -> threading.Thread:
        t = threading.Thread(target=serve, args=(stamp, FdLink(master)),
                             kwargs={"stop": stop, **kw}, daemon=True)
        t.start()
        threads.append(t)
        return t

    yield start, port
    stop.set()
    for t in threads:
        t.join(5)
    port.close()
    os.close(slave)
    os.close(master)


def test_request_reaches_a_waiting_serin(served, programs):
    start, port = served
    s = Stamp.from_file(programs / "servo_refresh.bs2")
    start(s, factor=0.0, floor_s=0.5)
    assert port.read(1) == b"R"
    port.write(b"C800\r")
    assert port.read(1) == b"R"
    assert s.var("centre") == 800
    assert [p.width for p in s.servo.on_pin(12)][10:20] == [750 + 10 * k for k in range(10)]


def test_bytes_sent_while_busy_are_lost(served):
    start, port = served
    s = Stamp.from_source(BUSY_THEN_LISTEN, "busy.bs2")
    t = start(s, factor=1.0, floor_s=0.05)
    assert port.read(1) == b"A"
    port.write(b"Z")  # the program is in its 600 ms PAUSE: nobody listens
    assert port.read(1) == b"B"
    port.write(b"Q")  # now it waits in SERIN
    assert port.read(4) == b"gotQ"
    t.join(5)
    assert s.state == "ended" and s.line(16).lost == 1


def test_silent_host_gets_the_timeout_branch(served):
    start, port = served
    s = Stamp.from_source(BUSY_THEN_LISTEN, "busy.bs2")
    start(s, factor=0.0, floor_s=0.05)
    assert port.read(3) == b"ABT"


FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "servobot.bs2"


@pytest.mark.skipif(not FIRMWARE.exists(), reason="no firmware/servobot.bs2 here")
def test_firmware_answers_hello_over_the_pty(served):
    start, port = served
    start(Stamp.from_file(FIRMWARE), factor=0.0, floor_s=0.5, echo=True)
    boot_ready = port.read(8 + 7)
    assert boot_ready[3] == 0xC1 and boot_ready[8 + 3] == 0xC0  # BOOT, READY
    hello = bytes.fromhex("A55A030101000000FA")
    port.write(hello)
    assert port.read(9) == hello  # the programming port's echo
    reply = port.read(9)
    assert reply[:5] == bytes.fromhex("A55A038101") and (sum(reply[2:]) & 0xFF) == 0xFF
