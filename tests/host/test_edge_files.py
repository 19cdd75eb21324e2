"""Files at the edge: undecodable bytes in a file a command reads, and an output path that
cannot be written, are one line naming the problem and exit code 2, never a traceback."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from pac_host.cli.main import main

# bytes that are no UTF-8 text: a BOM-less UTF-16 start
BAD = b"\xff\xfe{\x00\"\x00"


def _one_line_exit_2(args: list[str]) -> str:
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2, res.output
    assert isinstance(res.exception, SystemExit), res.exception  # not an escaped error
    line, = res.output.strip().splitlines()
    assert line.startswith("pac-host: error: ")
    return line


@pytest.mark.parametrize("args", [
    ["table", "show", "--table", "{bad}"],
    ["simulate", "--table", "{bad}", "--turn-cycle", "12:3"],
    ["diagnose", "--model", "{bad}", "--runs", "{bad}"],
    ["diagnose", "--model", "shifted", "--runs", "{bad}"],
    ["sweep", "{bad}", "--out", "{tmp}/sweep"],
    ["optimize", "--table", "shifted", "--shapes", "{bad}", "--evaluations", "100"],
])
def test_undecodable_input_is_one_line_naming_the_file(tmp_path, args):
    bad = tmp_path / "bad.json"
    bad.write_bytes(BAD)
    line = _one_line_exit_2([a.format(bad=bad, tmp=tmp_path) for a in args])
    assert str(bad) in line or "bad.json" in line, line


@pytest.mark.parametrize("args", [
    ["table", "export", "{blocked}/t.json", "--table", "measured"],
    ["simulate", "--table", "shifted", "--turn-cycle", "12:3", "--plot", "{blocked}/p.png"],
])
def test_an_output_path_that_cannot_be_written_is_one_line(tmp_path, args):
    """A path through a regular file cannot be created (unlike a read-only folder, this holds
    for root too, as CI runs)."""
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    line = _one_line_exit_2([a.format(blocked=blocked) for a in args])
    assert "a-file" in line, line
