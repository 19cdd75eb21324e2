"""The gait-cycle periods robot time is counted in (pac_host.learning.robot_time) are the
firmware's:
a STEP of three gait cycles of each id, timed in Stamp time from one READY to the next."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pac_host.learning.robot_time import GAIT_PERIOD_S
from pac_sim.pbasic import Stamp

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "servobot.bs2"
STEP = 0x05

pytestmark = pytest.mark.skipif(not FIRMWARE.exists(), reason="no firmware/servobot.bs2 here")


def period(gid: int, cycles: int = 3) -> float:
    s = Stamp.from_file(FIRMWARE)
    s.run_until_serin(2.0)
    body = bytes([3, STEP, 1, gid, cycles, 0])
    s.feed(b"\xa5\x5a" + body + bytes([(0xFF - sum(body)) & 0xFF]))
    ready = []
    for _ in range(cycles):
        s.run_until_serin(5.0)
        ready.append(s.now_us)
        s.advance(200_000)  # the host stays silent: the listening window times out
    return (ready[2] - ready[1]) / 1e6  # a gait cycle in the middle of a run


@pytest.mark.parametrize("gid", [0, 15, 16, 24])
def test_gait_period_is_the_firmwares(gid):
    assert period(gid) == pytest.approx(GAIT_PERIOD_S[gid], abs=0.002)


def test_harder_turns_are_shorter():
    assert np.all(np.diff(GAIT_PERIOD_S[:16]) > 0) and np.all(np.diff(GAIT_PERIOD_S[16:]) > 0)
