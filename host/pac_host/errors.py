"""Typed errors. The CLI turns each into one line on stderr and an exit code."""


class PacError(Exception):
    """Base class of every error the toolkit raises on purpose."""

    exit_code = 1


class InputError(PacError, ValueError):
    """Bad user input: a malformed file, an out-of-range id, a bad option value (exit 2)."""

    exit_code = 2
