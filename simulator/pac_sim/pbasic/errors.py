"""Errors of the PBASIC interpreter, each naming the source line (``file:line: message``)."""

from __future__ import annotations

from pac_host.errors import InputError, PacError


def where(filename: str, line: int) -> str:
    """The ``file:line`` prefix every message carries."""
    return f"{filename}:{line}" if line else filename


class PbasicSyntaxError(InputError):
    """The source is not valid PBASIC 2.5, or uses a part outside the supported subset."""

    def __init__(self, filename: str, line: int, message: str) -> None:
        self.filename, self.line, self.message = filename, line, message
        super().__init__(f"{where(filename, line)}: {message}")


class PbasicRuntimeError(PacError):
    """The program did something the Stamp would fail at (GOSUB nesting, bad RETURN...)."""

    def __init__(self, filename: str, line: int, message: str) -> None:
        self.filename, self.line, self.message = filename, line, message
        super().__init__(f"{where(filename, line)}: {message}")


class StampNotListening(PacError):
    """The program ran for the given Stamp time without entering SERIN."""


class StampEnded(PacError):
    """The program reached END or STOP (or ran off its end) while the caller waited for SERIN."""
