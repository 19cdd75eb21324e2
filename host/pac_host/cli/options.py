"""Option types and helpers shared by the commands (parsing stays in the CLI layer)."""

from __future__ import annotations

import sys

import click

from pac_host.errors import InputError
from pac_host.model import GaitTable, parse_effect, resolve_table


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


def load_with_effects(table_spec: str, effect_specs: tuple[str, ...] = ()) -> GaitTable:
    """Resolve a table and add effects given on the command line to the table's own."""
    table = resolve_table(table_spec)
    extra = [parse_effect(s) for s in effect_specs]
    names = [e.name for e in table.effects] + [e.name for e in extra]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise InputError(f"effect {sorted(dup)[0]} given twice")
    return table.with_effects(tuple(table.effects) + tuple(extra)) if extra else table


def progress_enabled() -> bool:
    """Progress bars go to stderr, and only when it is a terminal."""
    return sys.stderr.isatty()


def profile_option():
    from pac_host import profiles

    return click.option(
        "--profile", default=profiles.DEFAULT, show_default=True,
        type=click.Choice(sorted(profiles.PROFILES)),
        help="paper: the paper's 40 CGA generations between punctuations; default: anytime "
             "PAL, a budget of search evaluations per punctuation.")


def search_evaluations_option():
    return click.option(
        "--search-evaluations", type=int, default=None,
        help="Turn-cycle search evaluations per punctuation (default profile; "
             "overrides the profile's).")


def profile_pal(profile: str, search_evaluations: int | None, **fields):
    """The PAL settings of a profile, with the command's own settings on top."""
    from dataclasses import replace

    from pac_host import profiles
    from pac_host.pal import PALConfig

    cfg = profiles.apply(profile, replace(PALConfig(), **fields))
    if search_evaluations is not None:
        if cfg.search == "cga":
            raise InputError("--search-evaluations needs an anytime profile, not "
                             f"--profile {profile}")
        cfg = replace(cfg, search_evaluations=search_evaluations)
    cfg.check()
    return cfg
