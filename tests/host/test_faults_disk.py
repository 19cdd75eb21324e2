"""Faults at the operating system's edge: a disk that fills up during a run, and an output
folder that may not be written. Each is one line on stderr and an exit code, never a
traceback; what was written before stays whole, and a run goes on with --resume to the results
of a run that never stopped."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from pac_host import files
from pac_host.cli.main import main
from pac_host.errors import FileFault


class _FullFile:
    """A file whose next write puts half its bytes on the disk, then finds the disk full."""

    def __init__(self, f):
        self._f = f

    def write(self, data):
        self._f.write(data[: len(data) // 2])
        self._f.flush()
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def __getattr__(self, name):
        return getattr(self._f, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()


def disk_full(monkeypatch, name: str, nth: int = 1, error: type[OSError] | None = None) -> list:
    """The ``nth`` opening for writing of the file called ``name`` (written directly, or
    through its temporary file) by :mod:`pac_host.files` finds the disk full; with ``error``
    (PermissionError, say) the opening itself fails with it. Returns the paths refused."""
    real = open
    seen: list[Path] = []

    def fake(file, mode="r", *args, **kw):
        p = Path(file)
        if p.name.removesuffix(".tmp") == name and any(c in mode for c in "wa+"):
            seen.append(p)
            if len(seen) == nth:
                if error is not None:
                    raise error(errno.EACCES, os.strerror(errno.EACCES), str(p))
                return _FullFile(real(file, mode, *args, **kw))
        return real(file, mode, *args, **kw)

    monkeypatch.setattr(files, "open", fake, raising=False)
    return seen


def one_line(res, code: int, *words: str) -> str:
    """The run ended with exit ``code`` and one line on stderr (no traceback) holding
    ``words``; returns it."""
    assert res.exit_code == code, res.output
    assert isinstance(res.exception, SystemExit), res.exception  # not an escaped error
    assert "Traceback" not in res.output
    line, = res.stderr.strip().splitlines()
    assert line.startswith("pac-host: error: "), line
    for w in words:
        assert w in line, line
    return line


def test_write_atomic_keeps_the_previous_file_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "state.json"
    files.write_atomic(path, "old\n")
    disk_full(monkeypatch, "state.json")
    with pytest.raises(FileFault, match="state.json: cannot write .No space left on device."):
        files.write_atomic(path, "new " * 1000)
    assert path.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["state.json"]


def test_append_text_leaves_no_half_line(tmp_path, monkeypatch):
    path = tmp_path / "log.jsonl"
    files.append_text(path, '{"a": 1}\n')
    disk_full(monkeypatch, "log.jsonl")
    with pytest.raises(FileFault, match="log.jsonl: cannot write"):
        files.append_text(path, '{"a": 2, "b": "' + "x" * 100 + '"}\n')
    assert path.read_text() == '{"a": 1}\n'


def test_a_torn_last_line_is_cut_before_appending(tmp_path):
    path = tmp_path / "observations.jsonl"
    path.write_text('{"a": 1}\n{"a": ')
    files.cut_torn_line(path)
    assert path.read_text() == '{"a": 1}\n'
    path.write_text('{"a": 1}')  # whole, only its newline missing: kept
    files.cut_torn_line(path)
    assert path.read_text() == '{"a": 1}\n'


def test_a_plot_on_a_full_disk_is_one_line(tmp_path, monkeypatch):
    disk_full(monkeypatch, "p.png")
    res = CliRunner().invoke(main, ["simulate", "--table", "shifted", "--turn-cycle", "12:3",
                                    "--plot", str(tmp_path / "p.png")])
    one_line(res, 1, f"{tmp_path / 'p.png'}: cannot write (No space left on device)")
    assert not list(tmp_path.iterdir())


# the paper's profile at its smallest: a run of the experiment takes about a second
TINY = ["--seeds", "1", "--generations", "40", "--initial-generations", "10", "--methods",
        "partial", "--optimum-runs", "1", "--optimum-generations", "10", "--profile", "paper",
        "--model-generations", "5", "--budget", "100", "--quiet"]


def _experiment(out: Path, *args: str):
    return CliRunner().invoke(main, ["experiment", *TINY, "--out", str(out), *args])


def test_experiment_on_a_full_disk_resumes_to_the_same_summary(tmp_path, monkeypatch):
    """The disk fills at the second punctuation's log line, then again at the plots: each is
    one line (exit 1) saying how to go on; the log keeps whole lines only, a torn last line (as
    a crash leaves) is ignored, and the resumed run's summary is the uninterrupted run's."""
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert _experiment(whole).exit_code == 0
    with monkeypatch.context() as m:
        disk_full(m, "log.jsonl", nth=2)
        line = one_line(_experiment(cut), 1, "log.jsonl: cannot write (No space left on device)",
                        f"`pac-host experiment --out {cut} --resume` continues it")
    assert str(cut) in line
    log = (cut / "log.jsonl").read_text()
    assert log.endswith("\n") and len(log.splitlines()) == 1
    (cut / "log.jsonl").write_text(log + log[: len(log) // 2])  # a crash's torn line
    with monkeypatch.context() as m:
        disk_full(m, "coverage_means.png")
        one_line(_experiment(cut, "--resume"), 1,
                 "coverage_means.png: cannot write (No space left on device)",
                 f"the results are in {cut / 'summary.json'}")
    assert not list(cut.glob("*.tmp"))
    summary = json.loads((cut / "summary.json").read_text())
    assert summary["runs"] == json.loads((whole / "summary.json").read_text())["runs"]
    assert sorted((cut / "log.jsonl").read_text().splitlines()) == \
        sorted((whole / "log.jsonl").read_text().splitlines())


def test_a_corrupt_line_inside_the_log_is_still_refused(tmp_path):
    """Only a torn last line is ignored: a bad line with whole lines after it names its file
    and line (exit 2)."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.json").write_text(json.dumps({"format": "pac-experiment-config/1",
                                                 "options": {}, "typed": []}))
    (out / "log.jsonl").write_text('{"seed": 0\n{"seed": 0, "method": "partial"}\n')
    one_line(_experiment(out, "--resume"), 2, f"{out / 'log.jsonl'}:1: not a JSON line")


@pytest.fixture
def read_only(tmp_path, monkeypatch):
    """A folder that may not be written: chmod 0o555, or where permissions do not bind
    (root), every write into it refused with PermissionError as the system would."""
    folder = (tmp_path / "ro").resolve()
    folder.mkdir()
    folder.chmod(0o555)
    if os.geteuid() == 0:
        real_open, real_mkdir = open, Path.mkdir

        def refused(p):
            return PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(p))

        def fake_open(file, mode="r", *args, **kw):
            if any(c in mode for c in "wax+") and Path(file).resolve().is_relative_to(folder):
                raise refused(file)
            return real_open(file, mode, *args, **kw)

        def fake_mkdir(self, *args, **kw):
            if self.resolve().is_relative_to(folder) and self.resolve() != folder:
                raise refused(self)
            return real_mkdir(self, *args, **kw)

        monkeypatch.setattr(files, "open", fake_open, raising=False)
        monkeypatch.setattr(Path, "mkdir", fake_mkdir)
    yield folder
    folder.chmod(0o755)


@pytest.mark.parametrize("args", [
    ["table", "export", "{ro}/t.json", "--table", "measured"],
    ["simulate", "--table", "shifted", "--turn-cycle", "12:3", "--plot", "{ro}/p.png"],
    ["experiment", *TINY, "--out", "{ro}"],
    ["experiment", *TINY, "--out", "{ro}/new"],
    ["evolve", "--out", "{ro}", "--generations", "0", "--quiet"],
])
def test_a_read_only_output_folder_is_one_line(read_only, args):
    res = CliRunner().invoke(main, [a.format(ro=read_only) for a in args])
    line = one_line(res, 2, str(read_only))
    assert "ermission denied" in line, line
    assert not list(read_only.rglob("*"))
