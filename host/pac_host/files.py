"""Reading input files with one clear error, and writing result files so that a crash never
leaves half of one."""

from __future__ import annotations

import os
from pathlib import Path

from pac_host.errors import InputError


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
    """Write ``text`` to ``path`` through a temporary file beside it, then rename it over."""
    p = Path(path)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, p)
