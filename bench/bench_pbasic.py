"""PBASIC interpreter speed: Stamp instructions per host second on a loop-heavy program.

Target: at least 200,000 instructions/s, 50 times the real BS2's ~4000/s, so firmware-in-the-loop
tests run faster than real time. Also reports the firmware's gait cycle (PULSOUT-heavy) speed as
Stamp seconds per host second when ``firmware/servobot.bs2`` is present.
"""

from __future__ import annotations

import time
from pathlib import Path

from pac_sim.pbasic import Stamp

ROOT = Path(__file__).resolve().parents[1]
TARGET_IPS = 200_000

LOOP_PROGRAM = """' {$STAMP BS2}
' {$PBASIC 2.5}
i     VAR Word
j     VAR Byte
acc   VAR Word
arr   VAR Byte(8)
flags VAR Byte
DO
  FOR j = 0 TO 7
    arr(j) = arr(j) + j * 3 // 251
    acc = acc + arr(j) ^ (acc << 1)
    IF acc > 40000 THEN acc = acc - 40000
    flags.BIT0(j) = acc.BIT0
  NEXT
  SELECT flags
    CASE 0 TO 63
      i = i + 1
    CASE ELSE
      i = i + 2
  ENDSELECT
LOOP
"""


def instructions_per_second(stamp_seconds: float) -> tuple[float, int, float]:
    s = Stamp.from_source(LOOP_PROGRAM, "bench_loop.bs2")
    t0 = time.perf_counter()
    s.run_for(stamp_seconds)
    wall = time.perf_counter() - t0
    return s.icount / wall, s.icount, wall


def firmware_speed(cycles: int) -> dict | None:
    path = ROOT / "firmware" / "servobot.bs2"
    if not path.exists():
        return None
    s = Stamp.from_file(path)
    s.run_until_serin(2.0)
    chk = (~(3 + 5 + 1 + 12 + cycles)) & 0xFF
    s.feed(bytes([0xA5, 0x5A, 3, 5, 1, 12, cycles, 0, chk]))
    t0 = time.perf_counter()
    stamp0 = s.now_us
    for _ in range(cycles):
        s.run_until_serin(5.0)
        s.advance(200_000)  # no host reply: the listening window times out
    wall = time.perf_counter() - t0
    stamp_s = (s.now_us - stamp0) / 1e6
    return {"gait_cycles": cycles, "stamp_s": round(stamp_s, 3), "wall_s": round(wall, 3),
            "stamp_s_per_host_s": round(stamp_s / wall, 1), "pulses": len(s.servo.pulses)}


def run(quick: bool) -> dict:
    best = 0.0
    count = 0
    for _ in range(2 if quick else 3):
        ips, count, _ = instructions_per_second(50.0 if quick else 250.0)
        best = max(best, ips)
    out: dict = {
        "loop_instructions": count,
        "instructions_per_s": round(best),
        "speedup_vs_bs2": round(best / 4000, 1),
        "targets": {
            "instructions_per_s": {"value": round(best), "target": f">= {TARGET_IPS}",
                                   "met": best >= TARGET_IPS},
        },
    }
    fw = firmware_speed(3 if quick else 10)
    if fw is not None:
        out["firmware"] = fw
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick=True), indent=1))
