"""Option types and helpers shared by the commands (parsing stays in the CLI layer)."""

from __future__ import annotations

import sys

import click

from pac_host.model import load_with_effects  # noqa: F401  (re-exported for the commands)


def table_option(default: str = "measured", help_text: str | None = None):
    return click.option(
        "--table",
        "table_spec",
        default=default,
        show_default=True,
        metavar="measured|shifted|FILE",
        help=help_text or "Gait table: a built-in name or a pac-gait-table/1 JSON file.",
    )


def effect_option():
    return click.option(
        "--effect",
        "effect_specs",
        multiple=True,
        metavar="NAME:P=V,...",
        help="Add an unmodelled effect, e.g. transition:alpha=0.3 (repeatable).",
    )


def progress_enabled() -> bool:
    """Progress bars go to stderr, and only when it is a terminal."""
    return sys.stderr.isatty()
