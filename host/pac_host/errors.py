"""Typed errors, and the one place where an error becomes an exit code.

The CLIs turn every error the toolkit raises on purpose (:data:`TOOLKIT_ERRORS`: the host's
:class:`PacError` and the protocol package's own ``PacProtocolError``) into one line on stderr and
:func:`exit_code` (2 for usage and input errors).

>>> from pac_protocol.errors import NoAnswer, PortError
>>> exit_code(InputError("bad")), exit_code(PortError("no port")), exit_code(NoAnswer("silent"))
(2, 2, 1)
"""

from __future__ import annotations

from pac_protocol.errors import PacProtocolError
from pac_protocol.errors import UsageError as ProtocolUsageError


class PacError(Exception):
    """Base class of every error the host toolkit raises on purpose."""

    exit_code = 1


class InputError(PacError, ValueError):
    """Bad user input: a malformed file, an out-of-range id, a bad option value (exit 2)."""

    exit_code = 2


class FileFault(PacError):
    """The operating system failed a read or write during a run (a full disk, an I/O error):
    exit 1. What was written before it stays whole (:mod:`pac_host.files`)."""


#: Every error raised on purpose, by the host or by the protocol layer below it.
TOOLKIT_ERRORS: tuple[type[Exception], ...] = (PacError, PacProtocolError)


def exit_code(error: BaseException) -> int:
    """The exit code for an error the toolkit raised on purpose (1 for anything else)."""
    if isinstance(error, PacError):
        return error.exit_code
    if isinstance(error, ProtocolUsageError):
        return 2
    return 1


# the operating system's refusals that come from what the user named (a path to read or write
# that does not exist, is not a folder or may not be written): input errors, exit 2; any other
# (a full disk, a vanished device) is a fault during the run, exit 1
_INPUT_OS_ERRORS = (FileNotFoundError, NotADirectoryError, IsADirectoryError, PermissionError,
                    FileExistsError)


def os_error_line(error: OSError | UnicodeDecodeError) -> tuple[str, int]:
    """One line naming what the operating system refused, and its exit code: the safety net
    for a read or write no reader or writer turned into an :class:`InputError` itself.

    >>> os_error_line(PermissionError(13, "Permission denied", "out/log.jsonl"))
    ('out/log.jsonl: Permission denied', 2)
    >>> os_error_line(OSError(28, "No space left on device", "out/state.json"))
    ('out/state.json: No space left on device', 1)
    >>> os_error_line(UnicodeDecodeError("utf-8", b"\\xff", 0, 1, "invalid start byte"))
    ('a file is not UTF-8 text (invalid start byte at offset 0)', 2)
    """
    if isinstance(error, UnicodeDecodeError):
        return f"a file is not UTF-8 text ({error.reason} at offset {error.start})", 2
    what = error.strerror or str(error)
    where = error.filename if error.filename is not None else ""
    text = f"{where}: {what}" if where else what
    return text, 2 if isinstance(error, _INPUT_OS_ERRORS) else 1


def os_error(error: OSError, path: object = None, doing: str = "") -> PacError:
    """The typed error for what the operating system refused: one line naming the file
    (``path``, else the error's own) and the problem; an :class:`InputError` (exit 2) for a
    path the user named that cannot be used (missing, not a folder, not writable), else a
    :class:`FileFault` (exit 1). ``doing``: what was being done ("cannot write").

    >>> e = os_error(OSError(28, "No space left on device"), "out/state.json", "cannot write")
    >>> type(e).__name__, str(e)
    ('FileFault', 'out/state.json: cannot write (No space left on device)')
    >>> os_error(PermissionError(13, "Permission denied", "out/t.json")).exit_code
    2
    """
    where = path if path is not None else error.filename
    what = error.strerror or str(error)
    text = f"{doing} ({what})" if doing else what
    if where is not None:
        text = f"{where}: {text}"
    return (InputError if isinstance(error, _INPUT_OS_ERRORS) else FileFault)(text)


def with_hint(error: PacError, hint: str) -> PacError:
    """``error`` again, of its own kind (so its exit code), with ``hint`` after its text: what
    to do next (resume the run, say). For errors made of one message, as the toolkit's are.

    >>> str(with_hint(FileFault("log.jsonl: cannot write"), "resume with --resume OUT"))
    'log.jsonl: cannot write; resume with --resume OUT'
    """
    return type(error)(f"{error}; {hint}")
