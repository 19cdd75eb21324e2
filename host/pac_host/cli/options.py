"""Option types and helpers shared by the commands (parsing stays in the CLI layer)."""

from __future__ import annotations

import sys

import click

from pac_host.limits import Bound
from pac_host.model import load_with_effects  # noqa: F401  (re-exported for the commands)


class Bounded(click.ParamType):
    """An integer option held to a :class:`~pac_host.limits.Bound`: outside it, one line naming
    the option, the range and why, and exit 2. The help shows the range as the metavar."""

    name = "integer"

    def __init__(self, bound: Bound) -> None:
        self.bound = bound

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        return self.bound.describe()

    def convert(self, value, param, ctx) -> int:
        v = value if isinstance(value, int) else click.INT.convert(value, param, ctx)
        name = param.opts[0] if param is not None and param.opts else "value"
        return self.bound.check(v, name)


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
