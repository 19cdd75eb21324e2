"""Option types and helpers shared by the commands (parsing stays in the CLI layer)."""

from __future__ import annotations

import sys

import click

from pac_host.errors import InputError
from pac_host.model import load_with_effects  # noqa: F401  (re-exported for the commands)
from pac_host.model.effects_module import load_effects_module


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


def _load_modules(ctx: click.Context, param: click.Parameter, value: tuple[str, ...]) -> None:
    try:
        for path in value:
            load_effects_module(path)
    except InputError as e:  # raised while parsing, before the command's own error handling
        click.echo(f"{ctx.find_root().info_name}: error: {e}", err=True)
        ctx.exit(e.exit_code)


def effects_module_option():
    """``--effects-module FILE`` (repeatable): user-defined effects, loaded before any other
    option is used, so tables and ``--effect`` may name them."""
    return click.option(
        "--effects-module",
        multiple=True,
        metavar="FILE.py",
        is_eager=True,
        expose_value=False,
        callback=_load_modules,
        help="Python file defining effects with pac_host.model.effects.register_effect "
             "(repeatable; see docs/diagnose.md).",
    )


def progress_enabled() -> bool:
    """Progress bars go to stderr, and only when it is a terminal."""
    return sys.stderr.isatty()
