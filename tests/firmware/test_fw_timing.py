"""The timing budget, measured in Stamp time by running the firmware source in the project's
PBASIC interpreter, and checked against the table in firmware/README.md.

The interpreter's clock is the BS2's published rates (``pac_sim.pbasic.clock``): 250 us per
instruction, PULSOUT adds its pulse (2 us per unit), SEROUT 1.04 ms per byte at 9600 baud, a
SERIN that hears nothing lasts its timeout. No Stamp was timed.
"""

from __future__ import annotations

import re

import pytest
from fw_build import FIRMWARE, SOURCE
from fw_stamp import PROGRAMMING_PORT, const, gait_cycle, lift_pins

from pac_protocol.messages import Step
from pac_sim.pbasic import Stamp

REFRESH_RANGE_MS = (15.0, 25.0)
STRAIGHT = 15


def _diffs(ts: list[int]) -> list[int]:
    return [b - a for a, b in zip(ts, ts[1:], strict=False)]


def budget(text: str) -> dict[str, float]:
    s = Stamp.from_source(text, "servobot.bs2")
    lifts = list(lift_pins(s))
    refresh, cycles = [], []
    for g in range(32):
        n0, t0 = len(s.servo.pulses), s.now_us
        acts = gait_cycle(s, g)
        cycles.append(s.now_us - t0)
        pulses = s.servo.pulses[n0:]
        for pin in lifts:
            refresh += _diffs([p.t_us for p in pulses if p.pin == pin])
    # two gait cycles of a STEP with a silent host: the boundary between them
    r = Stamp.from_source(text, "servobot.bs2")
    r.run_until_serin(2.0)
    r.output.take(PROGRAMMING_PORT)
    r.feed(Step(STRAIGHT, 2).encode(1), echo=False)
    w = r.run_until_serin(5.0)  # after gait cycle 1: CYCLE, READY(2), listening
    listen_us = w.deadline_us - w.since_us
    r.advance(w.deadline_us - r.now_us + 1)
    r.run_until_serin(5.0)  # gait cycle 2, DONE, READY idle
    lift0 = [p.t_us for p in r.servo.pulses if p.pin == lifts[0]]
    n = len(acts)
    return {
        "activations": n,
        "refresh_min_ms": min(refresh) / 1000,
        "refresh_max_ms": max(refresh) / 1000,
        "cycle_min_s": min(cycles) / 1e6,
        "cycle_max_s": max(cycles) / 1e6,
        "listen_ms": listen_us / 1000,
        "gap_ms": max(_diffs(lift0)) / 1000,
        "period_s": (lift0[n] - lift0[0]) / 1e6,
    }


@pytest.fixture(scope="module")
def figures() -> dict[str, float]:
    return budget(SOURCE.read_text(encoding="latin-1"))


def test_servo_refresh_within_15_to_25_ms_for_every_gait_id(figures):
    lo, hi = REFRESH_RANGE_MS
    assert figures["activations"] == 58
    assert lo <= figures["refresh_min_ms"] <= figures["refresh_max_ms"] <= hi, figures


def test_listening_window_is_the_protocols_t_run(figures):
    s = Stamp.from_file(SOURCE)
    assert figures["listen_ms"] == const(s, "T_RUN") == 100
    assert figures["gap_ms"] > figures["listen_ms"]
    assert figures["period_s"] * 1000 == pytest.approx(
        figures["cycle_max_s"] * 1000 + figures["gap_ms"] - figures["refresh_max_ms"], rel=0.1)


def readme_table() -> dict[str, str]:
    text = (FIRMWARE / "README.md").read_text()
    return dict(re.findall(r"^\|\s*`(\w+)`\s*\|[^|]*\|\s*([\d.]+)\s*\|", text, re.M))


def test_readme_documents_the_measured_budget(figures):
    table = readme_table()
    assert set(figures) <= set(table), sorted(set(figures) - set(table))
    for key, value in figures.items():
        digits = len(table[key].split(".")[1]) if "." in table[key] else 0
        assert float(table[key]) == pytest.approx(round(value, digits), abs=10**-digits), key


def test_budget_moves_with_the_source_constants():
    src = SOURCE.read_text(encoding="latin-1")
    base = budget(src)
    slower = budget(re.sub(r"^(T_RUN\s+CON )100", r"\g<1>250", src, flags=re.M))
    assert slower["listen_ms"] == 250
    assert slower["gap_ms"] == pytest.approx(base["gap_ms"] + 150)
    longer = budget(re.sub(r"^(LIFT_DOWN\s+CON )700", r"\g<1>720", src, flags=re.M))
    assert longer["refresh_max_ms"] != pytest.approx(base["refresh_max_ms"])
