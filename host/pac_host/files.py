"""Reading input files with one clear error, and writing result files so that a crash or a
full disk never leaves half of one: result files are written whole and renamed over
(:func:`write_atomic`), logs appended a whole line at a time (:func:`append_text`), and a torn
last line of a log is ignored when it is read back (:func:`read_jsonl`)."""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

from pac_host.errors import InputError, os_error


def read_text(path: str | Path, what: str = "file") -> str:
    """The text of an input file; a missing, unreadable or undecodable one is one line
    (InputError) naming the file and what it was read as.

    >>> read_text("/no/t.json", "gait table")
    Traceback (most recent call last):
    ...
    pac_host.errors.InputError: /no/t.json: cannot read gait table (No such file or directory)
    """
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise InputError(f"{p}: cannot read {what}: not UTF-8 text (byte 0x{e.object[e.start]:02x} "
                         f"at offset {e.start})") from None
    except OSError as e:
        raise InputError(f"{p}: cannot read {what} ({e.strerror or e})") from None


def write_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file beside it, on the disk (fsync)
    before it is renamed over: a reader, or a run after a crash, finds the previous file or
    the new one, never half of one. When the write fails (a full disk, an I/O error, a folder
    that may not be written) the temporary file is removed, the previous file stays as it
    was, and the error is one line naming ``path`` (:func:`~pac_host.errors.os_error`).

    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp())
    >>> write_atomic(d / "a.json", "{}\\n"); sorted(p.name for p in d.iterdir())
    ['a.json']
    """
    write_atomic_with(path, lambda f: f.write(text.encode("utf-8")))


def write_atomic_with(path: str | Path, write: Callable[[BinaryIO], object]) -> None:
    """:func:`write_atomic` for a writer of a binary file (a plot's ``savefig``, say):
    ``write(f)`` writes the whole new content to ``f``."""
    p = Path(path)
    tmp = p.with_name(p.name + ".tmp")
    try:
        with open(tmp, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException as e:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        if isinstance(e, OSError):
            raise os_error(e, p, "cannot write") from None
        raise


def make_dirs(path: str | Path) -> Path:
    """``path`` as a folder, made with its parents if missing; one line if it cannot be."""
    p = Path(path)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise os_error(e, p, "cannot make the folder") from None
    return p


def append_text(path: str | Path, text: str) -> None:
    """Append whole lines (``text`` ends with a newline) to ``path`` in one write, flushed.
    When the write fails the file is cut back to where it was, so no half line stays behind
    (a crash may still leave one: :func:`read_jsonl` ignores it); the error is one line
    naming ``path``."""
    p = Path(path)
    try:
        f = open(p, "ab")
    except OSError as e:
        raise os_error(e, p, "cannot write") from None
    with f:
        end = f.tell()
        try:
            f.write(text.encode("utf-8"))
            f.flush()
        except OSError as e:
            with contextlib.suppress(OSError):
                f.truncate(end)
            raise os_error(e, p, "cannot write") from None


def read_jsonl(path: str | Path, what: str = "log") -> list[tuple[int, Any]]:
    """The JSON values of a JSON Lines file with their line numbers (blank lines skipped; a
    missing file is empty). A last line that is neither whole JSON nor ended by a newline is
    what a full disk or a crash leaves of an append: it is ignored, as if never written. Any
    other line that is not JSON is one line (InputError) naming the file and the line.

    >>> import tempfile
    >>> p = Path(tempfile.mkdtemp()) / "log.jsonl"
    >>> _ = p.write_text('{"a": 1}\\n\\n{"a": 2}\\n{"a": ')
    >>> read_jsonl(p)
    [(1, {'a': 1}), (3, {'a': 2})]
    >>> _ = p.write_text('{"a": 1}\\n{"a": \\n{"a": 2}\\n')
    >>> try:
    ...     read_jsonl(p)
    ... except InputError as e:
    ...     print(str(e).removeprefix(str(p)))
    :2: not a JSON line (Expecting value); cannot read log
    """
    p = Path(path)
    if not p.exists():
        return []
    text = read_text(p, what)
    lines = text.split("\n")  # the last item: what follows the last newline ("" if none)
    out = []
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            out.append((n, json.loads(line)))
        except json.JSONDecodeError as e:
            if n == len(lines):  # unterminated and unparseable: a torn append
                break
            raise InputError(f"{p}:{n}: not a JSON line ({e.msg}); cannot read {what}") from None
    return out


def cut_torn_line(path: str | Path) -> None:
    """Before appending to a JSON Lines file: cut off a torn last line (:func:`read_jsonl`),
    or end a whole last line that lacks its newline, so the next line starts on its own."""
    p = Path(path)
    if not p.exists():
        return
    data = p.read_bytes()
    if not data or data.endswith(b"\n"):
        return
    start = data.rfind(b"\n") + 1
    try:
        json.loads(data[start:])
        whole = True
    except ValueError:  # JSONDecodeError, or bytes that are not text
        whole = False
    try:
        if whole:
            append_text(p, "\n")
        else:
            with open(p, "r+b") as f:
                f.truncate(start)
    except OSError as e:
        raise os_error(e, p, "cannot write") from None
