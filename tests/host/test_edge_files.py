"""Files at the edge: undecodable bytes in a file a command reads, and an output path that
cannot be written, are one line naming the problem and exit code 2, never a traceback."""

from __future__ import annotations

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

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


# every file a command reads (besides the table, runs, sweep and shapes files above): a sweep's
# table, pac-sim's, and what `experiment --resume` reads back (evolve's: tests/link)
RESUMED_CONFIG = '{"format": "pac-experiment-config/1", "options": {}, "typed": []}'
READERS = {
    "sweep's actual": (["sweep", "{dir}/sweep.toml", "--out", "{dir}/out"], "bad.json",
                       {"sweep.toml": "[grid]\nactual = ['bad.json']\n"}),
    "pac-sim --table": (["--table", "{dir}/bad.json"], "bad.json", {}),
    "experiment's config.json": (["experiment", "--out", "{dir}", "--resume"], "config.json",
                                 {}),
    "experiment's log.jsonl": (["experiment", "--out", "{dir}", "--resume", "--quiet"],
                               "log.jsonl", {"config.json": RESUMED_CONFIG}),
    "table show": (["table", "show", "--table", "{dir}/bad.json"], "bad.json", {}),
}


def _undecodable(parts: tuple[bytes, bytes, bytes]) -> bytes:
    return b"".join(parts)


def _not_utf8(data: bytes) -> bool:
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return True
    return False


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(reader=st.sampled_from(sorted(READERS)),
       data=st.tuples(st.binary(max_size=12),
                      st.sampled_from([b"\xff", b"\x80", b"\xc3(", b"\xed\xa0\x80", b"\xf8"]),
                      st.binary(max_size=12)).map(_undecodable).filter(_not_utf8))
def test_undecodable_bytes_in_any_file_read_are_one_line(tmp_path_factory, reader, data):
    """Whatever the bytes and wherever they sit in the file, the command stops before any
    work with one line naming the file, exit 2."""
    from pac_sim.cli import main as pac_sim

    args, name, others = READERS[reader]
    folder = tmp_path_factory.mktemp("read")
    for other, text in others.items():
        (folder / other).write_text(text)
    (folder / name).write_bytes(data)
    command = pac_sim if reader.startswith("pac-sim") else main
    res = CliRunner().invoke(command, [a.format(dir=folder) for a in args])
    assert res.exit_code == 2, res.output
    assert isinstance(res.exception, SystemExit), res.exception
    line = res.stderr.strip().splitlines()[-1]
    assert line.startswith(("pac-host: error: ", "pac-sim: error: ")) and name in line, line
    assert "Traceback" not in res.output
