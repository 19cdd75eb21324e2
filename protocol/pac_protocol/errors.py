"""Typed errors of the wire protocol; all are ``pac_host.errors.PacError``, so the CLI maps them."""

from __future__ import annotations

from pac_host.errors import InputError, PacError


class ProtocolError(PacError):
    """Base of every protocol-level failure (exit 1)."""


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


class PortError(InputError):
    """The serial port does not exist, cannot be opened, or is not a serial device (exit 2)."""


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
