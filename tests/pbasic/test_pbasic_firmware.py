"""The ServoBot firmware itself, run in the interpreter: it leads the exchange, answers a request
and walks one gait cycle per id with the affecter's thrust counts in the servo trace.

Requests are built from the wire format (A5 5A 03 CMD SEQ P0 P1 P2 CHK, CHK making the byte
sum $FF) so this test needs only the firmware source. Skipped where the checkout has none.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from pac_sim.pbasic import Stamp

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "servobot.bs2"
STEP, HELLO = 0x05, 0x01

pytestmark = pytest.mark.skipif(not FIRMWARE.exists(), reason="no firmware/servobot.bs2 here")


def request(cmd: int, seq: int, p0: int = 0, p1: int = 0, p2: int = 0) -> bytes:
    body = bytes([3, cmd, seq, p0, p1, p2])
    return b"\xa5\x5a" + body + bytes([(0xFF - sum(body)) & 0xFF])


@pytest.fixture(scope="module")
def booted() -> Stamp:
    s = Stamp.from_file(FIRMWARE)
    s.run_until_serin(2.0)
    return s


def test_boot_then_listens_with_a_timeout(booted):
    s = Stamp.from_file(FIRMWARE)
    w = s.run_until_serin(2.0)
    out = s.output.take(16)
    assert out[:2] == b"\xa5\x5a" and out.count(b"\xa5\x5a") == 2  # BOOT, then READY
    assert w.pin == 16 and w.deadline_us is not None
    s.advance(w.deadline_us - s.now_us + 1)  # host silent: READY again after the timeout
    s.run_until_serin(2.0)
    assert s.output.take(16).count(b"\xa5\x5a") == 1


def test_hello_is_answered(booted):
    s = booted
    s.output.take()
    s.feed(request(HELLO, 0))
    s.run_until_serin(2.0)
    out = s.output.take(16)
    assert out.startswith(request(HELLO, 0))  # the programming port's echo comes first
    assert out[9:11] == b"\xa5\x5a" and out[12] == 0x81  # HELLO reply


@pytest.mark.parametrize("gid", range(32))
def test_one_gait_cycle_per_id(booted, gid):
    s = booted
    sym = s.program.symbols.con_value
    hips = [sym[f"HIP{leg}"] for leg in range(6)]
    lifts = [sym[f"LIFT{leg}"] for leg in range(6)]
    n0 = len(s.servo.pulses)
    s.feed(request(STEP, gid + 1, gid, 1, 0))
    s.run_until_serin(5.0)
    pulses = s.servo.pulses[n0:]
    count = Counter(p.pin for p in pulses)
    assert [count[p] for p in lifts] == [58] * 6  # 58 activations
    side, strength = gid >> 4, gid & 15
    thrust = min(2 * strength, 29)
    for leg, pin in enumerate(hips):
        affected = (leg % 2 == 0) == (side == 0)  # even legs are on the right
        assert count[pin] == (29 + thrust if affected else 58), (gid, leg)
    t = [p.t_us for p in pulses if p.pin == lifts[0]]
    periods = [b - a for a, b in zip(t, t[1:], strict=False)]
    assert 15_000 <= min(periods) and max(periods) <= 25_000
