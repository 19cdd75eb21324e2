"""Operators: strict left-to-right evaluation, 16-bit unsigned wrap, every operator's value."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pac_sim.pbasic import Stamp
from pac_sim.pbasic.operators import BINARY


def value_of(run, expr: str, decl: str = "") -> int:
    s = run(f"r VAR Word\na VAR Word\nb VAR Word\n{decl}\nr = {expr}\nEND\n")
    return s.var("r")


@pytest.mark.parametrize(
    ("expr", "expected"),
    [
        ("2 + 3 * 4", 20),  # left to right, no precedence
        ("2 + (3 * 4)", 14),
        ("10 - 2 * 3", 24),
        ("65535 + 1", 0),
        ("0 - 1", 65535),
        ("-5", 65531),
        ("-5 + 10", 5),  # unary binds to its operand only
        ("300 * 300", (300 * 300) & 0xFFFF),
        ("300 ** 300", (300 * 300) >> 16),
        ("$0180 */ $0200", (0x180 * 0x200 >> 8) & 0xFFFF),
        ("17 / 5", 3),
        ("17 // 5", 2),
        ("7 / 0", 0xFFFF),
        ("5 MIN 10", 10),
        ("50 MIN 10", 50),
        ("5 MAX 3", 3),
        ("$F0F0 & $FF00", 0xF000),
        ("$F0F0 | $0F00", 0xFFF0),
        ("$F0F0 ^ $FFFF", 0x0F0F),
        ("1 << 15", 0x8000),
        ("1 << 16", 0),
        ("$8000 >> 15", 1),
        ("~0", 0xFFFF),
        ("ABS -7", 7),
        ("SQR 1000", 31),
        ("DCD 4", 16),
        ("NCD 1000", 10),
        ("12345 DIG 0", 5),
        ("12345 DIG 3", 2),
        ("%1011 REV 4", 0b1101),
        ("%0001 REV 3", 0b100),
        ("$10 + %101 + \"A\"", 16 + 5 + 65),
    ],
)
def test_constant_operators(run, expr, expected):
    assert value_of(run, expr) == expected


@pytest.mark.parametrize(
    ("expr", "expected"),
    [("a + b * 4", (7 + 9) * 4), ("a - b", (7 - 9) & 0xFFFF), ("a / (b - 9)", 0xFFFF),
     ("b // a", 2), ("a << b", (7 << 9) & 0xFFFF), ("-a", 0x10000 - 7), ("a MAX b MIN 8", 8),
     ("b DIG (a - 7)", 9), ("SQR (a * b)", 7), ("ABS (a - b)", 2)],
)
def test_variable_operators(run, expr, expected):
    """The same operators compiled with variable operands (no constant folding)."""
    s = run(f"r VAR Word\na VAR Word\nb VAR Word\na = 7\nb = 9\nr = {expr}\nEND\n")
    assert s.var("r") == expected


OPS = ["+", "-", "*", "**", "*/", "/", "//", "MIN", "MAX", "&", "|", "^", "<<", ">>", "DIG"]


@settings(max_examples=60, deadline=None)
@given(
    vals=st.lists(st.integers(0, 0xFFFF), min_size=3, max_size=3),
    ops=st.lists(st.sampled_from(OPS), min_size=2, max_size=2),
)
def test_inlined_code_matches_reference_semantics(vals, ops):
    """Generated code on variables agrees with a left-to-right fold of the reference operators."""
    a, b, c = vals
    expected = BINARY[ops[1]](BINARY[ops[0]](a, b), c) & 0xFFFF
    src = (f"' {{$STAMP BS2}}\nr VAR Word\na VAR Word\nb VAR Word\nc VAR Word\n"
           f"a = {a}\nb = {b}\nc = {c}\nr = a {ops[0]} b {ops[1]} c\nEND\n")
    s = Stamp.from_source(src, "prop.bs2")
    s.run_for(1)
    assert s.var("r") == expected


def test_byte_and_nib_truncate(run):
    s = run("x VAR Byte\nn VAR Nib\nbt VAR Bit\nx = 300\nn = 17\nbt = 6\nEND\n")
    assert (s.var("x"), s.var("n"), s.var("bt")) == (44, 1, 0)


@pytest.mark.parametrize(
    ("cond", "taken"),
    [
        ("a + 1 > 7", True),  # comparisons bind looser than arithmetic
        ("a = 7 AND b = 9", True),
        ("a = 7 AND b = 8", False),
        ("a = 1 OR b = 9", True),
        ("NOT a = 7", False),
        ("NOT (a = 1) AND b > a", True),
        ("a = 7 XOR b = 9", False),
        ("a < b", True),
        ("a >= b", False),
        ("a <> b", True),
        ("a - b", True),  # non-zero counts as true
        ("a - 7", False),
        ("a = 1 OR b = 1 OR a + b = 16", True),
        ("a = 7 OR b = 1 AND b = 8", False),  # left to right: (a = 7 OR b = 1) AND b = 8
        ("b = 8 AND a = 1 OR a = 7", True),
    ],
)
def test_conditions(run, cond, taken):
    s = run(f"a VAR Byte\nb VAR Byte\nr VAR Bit\na = 7\nb = 9\nIF {cond} THEN r = 1\nEND\n")
    assert s.var("r") == int(taken)
