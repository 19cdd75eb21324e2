"""Anything outside the subset, or wrong, is an error naming file:line; never ignored."""

from __future__ import annotations

import pytest
from pac_sim.pbasic import PbasicSyntaxError, Stamp

# each program body gets two directive lines first, so its line 1 is line 3 of the file
CASES = [
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


@pytest.mark.parametrize(("body", "line", "message"), CASES)
def test_error_names_file_and_line(stamp, body, line, message):
    with pytest.raises(PbasicSyntaxError) as exc:
        stamp(body)
    assert exc.value.line == line, str(exc.value)
    assert str(exc.value).startswith(f"t.bs2:{line}: ")
    assert message in str(exc.value)


@pytest.mark.parametrize(
    ("directive", "message"),
    [("{$STAMP BS2sx}", "only {$STAMP BS2}"), ("{$PBASIC 2.0}", "only {$PBASIC 2.5}"),
     ("{$FOO}", "unknown directive")],
)
def test_directives(directive, message):
    with pytest.raises(PbasicSyntaxError, match=r"d\.bs2:1: .*" + message.replace("$", r"\$")):
        Stamp.from_source(directive + "\nEND\n", "d.bs2")


@pytest.mark.parametrize("form", ["{$STAMP BS2}", "' {$STAMP BS2}", "'{$STAMP BS2} comment"])
def test_directive_forms(form):
    assert Stamp.from_source(form + "\nEND\n", "d.bs2").run_for(1) == "ended"


def test_stamp_directive_is_required():
    with pytest.raises(PbasicSyntaxError, match=r"d\.bs2:1: \$STAMP directive not found"):
        Stamp.from_source("' just a comment\nEND\n", "d.bs2")


def test_case_insensitive(run):
    s = run("Counter var byte\ncounter = 3\nIF COUNTER = 3 then counter = counter + 1\nend\n")
    assert s.var("counter") == 4


def test_syntax_error_is_an_input_error():
    from pac_host.errors import InputError

    with pytest.raises(InputError):
        Stamp.from_source("' {$STAMP BS2}\nGOTO\n", "e.bs2")
