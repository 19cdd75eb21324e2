"""Typed errors of the wire protocol package.

The package stands alone: every error it raises on purpose is a :class:`PacProtocolError`, which
the command-line tools above it map to exit codes in one place.
Failures of the exchange are :class:`ProtocolError` (among them a port that vanishes mid-run,
:class:`PortVanished`); bad arguments from the caller (a turn cycle the Stamp cannot hold, a port
that cannot be opened) are :class:`UsageError`.
"""

from __future__ import annotations


class PacProtocolError(Exception):
    """Base of every error the protocol package raises on purpose."""


class UsageError(PacProtocolError, ValueError):
    """The caller asked for something the protocol cannot do: a bad argument, a bad port."""


class ProtocolError(PacProtocolError):
    """Base of every failure of the exchange with the Stamp."""


class FrameError(ProtocolError):
    """Bytes that are not one well-formed frame (strict parsing; the stream decoder skips them)."""

    code = "frame"


class BadSync(FrameError):
    code = "bad_sync"


class BadLength(FrameError):
    code = "bad_length"


class Truncated(FrameError):
    code = "truncated"


class TrailingBytes(FrameError):
    code = "trailing_bytes"


class BadCheck(FrameError):
    code = "bad_check"


class MessageError(ProtocolError):
    """A well-formed frame whose command or payload this protocol version does not define."""

    code = "message"


class UnknownCommand(MessageError):
    code = "unknown_command"


class BadPayload(MessageError):
    code = "bad_payload"


class PortError(UsageError):
    """The serial port does not exist, cannot be opened, or is not a serial device."""


class PortVanished(ProtocolError):
    """The serial port failed after it was opened: the device is gone (a USB adapter pulled, a
    pseudo-terminal whose other end closed). A fault during a run, unlike a :class:`PortError`
    at the start; nothing on this port can be retried."""


class NoAnswer(ProtocolError):
    """The device never announced it was listening, or never answered, within the retries."""


class VersionMismatch(ProtocolError):
    """HELLO answered with a protocol version this host does not speak."""


class Nacked(ProtocolError):
    """The Stamp refused a request with an error code that retrying cannot fix."""

    def __init__(self, message: str, command: int, error: int) -> None:
        super().__init__(message)
        self.command = command
        self.error = error


class StampReset(ProtocolError):
    """The Stamp announced a (re)boot while the host was waiting for it; its RAM state is gone."""
