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


#: Every error raised on purpose, by the host or by the protocol layer below it.
TOOLKIT_ERRORS: tuple[type[Exception], ...] = (PacError, PacProtocolError)


def exit_code(error: BaseException) -> int:
    """The exit code for an error the toolkit raised on purpose (1 for anything else)."""
    if isinstance(error, PacError):
        return error.exit_code
    if isinstance(error, ProtocolUsageError):
        return 2
    return 1
