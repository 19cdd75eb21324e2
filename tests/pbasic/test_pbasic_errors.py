"""Anything outside the subset, or wrong, is an error naming file:line; never ignored."""

from __future__ import annotations

import pytest

from pac_sim.pbasic import PbasicSyntaxError, Stamp


def test_error_names_file_and_line(stamp, error_case):
    body, line, message = error_case
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


@pytest.mark.parametrize("eol", ["\n", "\r\n", "\r"])
def test_line_endings(eol):
    src = eol.join(["' {$STAMP BS2}", "x VAR Byte", "x = 5", "y = 1", ""])
    with pytest.raises(PbasicSyntaxError, match=r"e\.bs2:4: undefined symbol Y"):
        Stamp.from_source(src, "e.bs2")
