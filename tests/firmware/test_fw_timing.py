"""The timing budget, recomputed from the firmware source and checked against firmware/README.md.

Model (the BS2's published figures; no Stamp was timed): a PBASIC statement costs 0.25 ms
(about 4000 statements/s); PULSOUT adds its pulse (2 us per unit); SEROUT takes 10 bits per
byte at 9600 baud; a SERIN that hears nothing lasts its timeout.
"""

from __future__ import annotations

import re

import pytest
from fw_build import FIRMWARE, SOURCE
from fw_pbasic import Program, split_top, strip_comment

STATEMENT_MS = 0.25
PULSE_UNIT_MS = 0.002
BYTE_MS = 10 / 9600 * 1000
REFRESH_RANGE_MS = (15.0, 25.0)


def section(prog: Program, label: str) -> list[str]:
    """Statements from ``label:`` to the next label."""
    start = next(i for i, ln in enumerate(prog.lines) if ln.lower() == f"{label.lower()}:")
    out = []
    for ln in prog.lines[start + 1 :]:
        if re.match(r"^\w+:$", ln):
            break
        if ln:
            out.append(ln)
    return out


def frame_bytes(statement: str) -> int:
    return len(split_top(statement[statement.index("[") + 1 : statement.rindex("]")], ","))


def budget(prog: Program) -> dict[str, float]:
    refresh = []
    cycles = []
    for g in range(32):
        acts = prog.gait_cycle(g)
        ms = [
            a.statements * STATEMENT_MS + sum(w for _, w in a.pulses) * PULSE_UNIT_MS
            for a in acts
        ]
        refresh += ms
        cycles.append(sum(ms))
    # between two gait cycles: the rest of Stride, then Listen up to and through its SERIN
    stride = section(prog, "Stride")
    after = stride[stride.index("GOSUB GaitCycle") + 1 : stride.index("GOSUB Listen") + 1]
    listen = section(prog, "Listen")
    before_serin = listen[: next(i for i, s in enumerate(listen) if s.startswith("SERIN")) + 1]
    stmts = after + before_serin
    serial_ms = sum(frame_bytes(s) * BYTE_MS for s in stmts if s.startswith("SEROUT"))
    listen_ms = float(prog.consts["T_RUN"])
    gap_ms = len(stmts) * STATEMENT_MS + serial_ms + listen_ms
    return {
        "activations": len(prog.gait_cycle(15)),
        "refresh_min_ms": min(refresh),
        "refresh_max_ms": max(refresh),
        "cycle_min_s": min(cycles) / 1000,
        "cycle_max_s": max(cycles) / 1000,
        "listen_ms": listen_ms,
        "gap_ms": gap_ms,
        "period_max_s": (max(cycles) + gap_ms) / 1000,
    }


@pytest.fixture(scope="module")
def figures() -> dict[str, float]:
    return budget(Program(SOURCE.read_text(encoding="latin-1")))


def test_servo_refresh_within_15_to_25_ms_for_every_gait_id(figures):
    lo, hi = REFRESH_RANGE_MS
    assert figures["activations"] == 58
    assert lo <= figures["refresh_min_ms"] <= figures["refresh_max_ms"] <= hi, figures


def test_listening_window_is_the_protocols_t_run(figures):
    assert figures["listen_ms"] == 100.0
    assert figures["gap_ms"] > figures["listen_ms"]


def readme_table() -> dict[str, str]:
    text = (FIRMWARE / "README.md").read_text()
    rows = re.findall(r"^\|\s*`(\w+)`\s*\|[^|]*\|\s*([\d.]+)\s*\|", text, re.M)
    return dict(rows)


def test_readme_documents_the_recomputed_budget(figures):
    table = readme_table()
    assert set(figures) <= set(table), sorted(set(figures) - set(table))
    for key, value in figures.items():
        digits = len(table[key].split(".")[1]) if "." in table[key] else 0
        assert float(table[key]) == pytest.approx(round(value, digits), abs=10**-digits), key


def test_budget_moves_with_the_source_constants():
    src = SOURCE.read_text(encoding="latin-1")
    slower = src.replace("T_RUN           CON 100", "T_RUN           CON 250")
    wider = re.sub(r"(LIFT_DOWN\s+CON )700", r"\g<1>900", src)
    base = budget(Program(src))
    assert budget(Program(slower))["gap_ms"] == pytest.approx(base["gap_ms"] + 150)
    # raising LIFT_DOWN lengthens right lift pulses, shortens mirrored left ones: changes sums
    assert budget(Program(wider))["refresh_max_ms"] != pytest.approx(base["refresh_max_ms"])


def test_strip_comment_keeps_strings():
    assert strip_comment("FwInfo DATA @0, \"S'B\", 1 ' tag") == "FwInfo DATA @0, \"S'B\", 1"
