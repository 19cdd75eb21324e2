"""Fixtures for the PBASIC interpreter tests: build a Stamp from a snippet and run it."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from pac_sim.pbasic import Stamp

PROGRAMS = Path(__file__).parent / "programs"
# each program body gets two directive lines first, so its line 1 is line 3 of the file
ERROR_CASES = [
    ("FREQOUT 1, 100, 440\n", 3, "FREQOUT is not supported"),
    ("x VAR Byte\nRANDOM x\n", 4, "RANDOM is not supported"),
    ("x VAR Byte\nx = 1\nFOO x\n", 5, "unknown statement FOO"),
    ("GOTO Nowhere\n", 3, "undefined label NOWHERE"),
    ("x VAR Byte\nx = y + 1\n", 4, "undefined symbol Y"),
    ("x VAR Byte\nIF x = 1 THEN\n  x = 2\n", 4, "IF at line 4 has no ENDIF"),
    ("x VAR Byte\nNEXT\n", 4, "NEXT without a matching opening statement"),
    ("x VAR Byte\nFOR x = 1 TO 3\nLOOP\n", 5, "LOOP without a matching opening statement"),
    ("DO\n  x VAR Byte\n", 3, "DO at line 3 has no LOOP"),
    ("EXIT\n", 3, "EXIT outside a DO or FOR loop"),
    ("A:\nA:\n", 4, "A is already defined (line 3)"),
    ("K CON 5\nK = 3\n", 4, "cannot assign to constant K"),
    ("x VAR Byte\nx = 2 +\n", 4, "expected a value"),
    ("x VAR Byte\nSERIN 16, 84, [WAIT(1,2,3,4,5,6,7)]\n", 4, "WAIT takes at most 6 bytes"),
    ("x VAR Byte\nx = \"ab\"\n", 4, "one character"),
    ("K CON K + 1\n", 3, "defined in terms of itself"),
    ("x VAR Byte\nx = 1 x\n", 4, "after the statement"),
    ("w VAR Word\nw = w.BIT16\n", 4, "unknown variable modifier .BIT16"),
    ("Led PIN 20\n", 3, "the BS2 has pins 0 to 15"),
    ("x VAR Byte\nHIGH 17\n", 4, "pin 17 does not exist"),
    ("PULSOUT 16, 750\n", 3, "pin 16 does not exist (BS2 pins: 0-15)"),
    ("SEROUT 17, 84, [1]\n", 3, "pin 17 does not exist (BS2 pins: 0-15, 16 = programming port)"),
    ("x VAR Byte\nx = 1 % 2\n", 4, "unexpected character"),
    ("x VAR Byte(0)\n", 3, "array length must be a positive number"),
    ("x VAR Byte\nIF x THEN\nELSE\nELSE\nENDIF\n", 6, "a second ELSE"),
    ("x VAR Byte\nSELECT x\n  x = 1\n  CASE 1\nENDSELECT\n", 5, "between SELECT and its first"),
]


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Tests asking for ``error_case`` run once per entry of ERROR_CASES."""
    if "error_case" in metafunc.fixturenames:
        metafunc.parametrize("error_case", ERROR_CASES,
                             ids=[f"line{line}-{msg[:24]}" for _, line, msg in ERROR_CASES])


@pytest.fixture
def error_cases() -> list[tuple[str, int, str]]:
    """(program body, line of the error in the file, message part) of every error test."""
    return ERROR_CASES
HEADER = "' {$STAMP BS2}\n' {$PBASIC 2.5}\n"


def build(body: str, name: str = "t.bs2") -> Stamp:
    """A Stamp for a program body (directives added; line numbers shift by 2)."""
    return Stamp.from_source(HEADER + body, name)


@pytest.fixture
def run() -> Callable[..., Stamp]:
    """Run a program body to its END (at most 10 s of Stamp time) and return the Stamp."""

    def _run(body: str, seconds: float = 10.0) -> Stamp:
        s = build(body)
        state = s.run_for(seconds)
        assert state == "ended", f"program did not end (state {state}, line {s.line_at()})"
        return s

    return _run


@pytest.fixture
def stamp() -> Callable[[str], Stamp]:
    """Build (not run) a Stamp from a program body."""
    return build


@pytest.fixture
def programs() -> Path:
    return PROGRAMS
