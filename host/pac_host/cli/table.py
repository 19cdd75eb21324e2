"""`pac-host table show|export`: look at a gait table, or write one out to edit."""

from __future__ import annotations

from pathlib import Path

import click

from pac_host.cli.options import (
    effect_option,
    effects_module_option,
    load_with_effects,
    step_noise_option,
    table_option,
)
from pac_host.model.table import COMPONENTS, save_table, side, strength


@click.group("table")
def table_group() -> None:
    """Show or export gait tables (the model of how each gait cycle moves the robot)."""


@table_group.command("show")
@table_option()
@effect_option()
@effects_module_option()
def show(table_spec: str, effect_specs: tuple[str, ...]) -> None:
    """Print a table: per gait cycle id, its turn side and strength and (F, T, dH).

    F is cm forward, T cm lateral (right positive), dH degrees of heading change (right
    positive) over one gait cycle.
    """
    table = load_with_effects(table_spec, effect_specs)
    click.echo(f"gait table: {table.name}")
    click.echo(f"{'id':>3} {'side':>5} {'str':>3} " + " ".join(f"{c:>7}" for c in COMPONENTS))
    for gid, row in enumerate(table.rows):
        turn = "right" if side(gid) == 0 else "left"
        vals = " ".join(f"{v:7.2f}" for v in row)
        click.echo(f"{gid:>3} {turn:>5} {strength(gid):>3} {vals}")
    for e in table.effects:
        click.echo(f"effect: {e}")
    if not table.step_noise.is_zero():
        click.echo(f"step noise: {table.step_noise.to_text()} (cm on F and T, deg on dH)")


@table_group.command("export")
@click.argument("path", type=click.Path(dir_okay=False, path_type=Path))
@table_option()
@effect_option()
@step_noise_option("Write this step noise into the file (cm on F and T, deg on dH; not "
                   "given: the table's own, if any; none: no noise).")
@effects_module_option()
def export(path: Path, table_spec: str, effect_specs: tuple[str, ...],
           step_noise: str | None) -> None:
    """Write a table as a pac-gait-table/1 JSON file to PATH."""
    table = load_with_effects(table_spec, effect_specs, step_noise)
    save_table(table, path)
    click.echo(f"wrote {path} ({table.name}, {len(table.effects)} effects)")


def register(main: click.Group) -> None:
    main.add_command(table_group)
