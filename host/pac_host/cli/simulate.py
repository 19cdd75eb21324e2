"""`pac-host simulate`: run one turn cycle on a gait table and report the path and coverage."""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from pac_host import limits
from pac_host.cli.options import (
    Bounded,
    effect_option,
    effects_module_option,
    load_with_effects,
    placed_text,
    placement_option,
    table_option,
)
from pac_host.coverage import DEFAULT_BUDGET, START_POSE, check_budget, parse_turn_cycle, simulate
from pac_host.coverage.placement import WALKS, parse_placement, placed_fitness, summary


@click.command("simulate")
@table_option()
@effect_option()
@effects_module_option()
@click.option("--turn-cycle", "turn_cycle", required=True, metavar="ID:REPS,...",
              help='Looped genes of gait cycle id (0..31) and repetitions (0..63), '
                   'e.g. "12:14,3:10".')
@click.option("--budget", default=DEFAULT_BUDGET, show_default=True,
              type=Bounded(limits.SIM_BUDGET),
              help="Gait cycles to run.")
@placement_option(help="Also walk the turn cycle from start poses drawn as a hand placement "
                       "with these standard deviations leaves them (none: only the exact start).")
@click.option("--walks", default=WALKS, show_default=True, type=click.IntRange(1, 100_000),
              help="With --placement-error: start poses drawn.")
@click.option("--seed", default=0, show_default=True, type=Bounded(limits.SEED),
              help="With --placement-error: seed of the drawn start poses.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object on stdout.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path),
              help="Also draw the path on the area to this PNG.")
def simulate_cmd(table_spec, effect_specs, turn_cycle, budget, placement, walks, seed, as_json,
                 plot) -> None:
    """Walk a turn cycle from the start pose (45, 30, 90) and score the path.

    Prints the pose after each gait cycle and the coverage figures: blocks covered, blocks
    covered exactly once, the coverage fitness 3R + c, and repeat visits. With
    --placement-error it also walks the turn cycle from --walks start poses drawn as a hand
    placement with those standard deviations leaves them, and gives the fitness's mean, median
    and 10th percentile: how much of the coverage survives putting the robot down by hand.

    Example: pac-host simulate --table shifted --turn-cycle 12:14,3:10 --placement-error 0.5,1
    """
    table = load_with_effects(table_spec, effect_specs)
    genes = parse_turn_cycle(turn_cycle)
    error = parse_placement(placement)
    budget = check_budget(budget)
    cov = simulate(table.rows, genes, budget, table.effects, START_POSE, keep_paths=True)
    placed = None
    if error is not None:
        fit = placed_fitness(table.rows, genes, error, walks, np.random.default_rng(seed),
                             budget, table.effects)
        placed = {"placement": error.to_text(), "seed": seed, **summary(fit)}
    poses = cov.poses[0]
    if plot:
        from pac_host.plots import coverage_path

        coverage_path(poses, cov.blocks[0], plot, f"{turn_cycle} on {table.name}", cov.row(0))
    if as_json:
        doc = {"poses": [[float(v) for v in p] for p in poses], **cov.row(0)}
        if placed is not None:
            doc["placed"] = placed
        click.echo(json.dumps(doc))
        return
    blocks = cov.blocks[0]
    click.echo(f"{'cycle':>5} {'x cm':>9} {'y cm':>9} {'h deg':>9}  block")
    for i, (p, b) in enumerate(zip(poses, blocks, strict=True)):
        block = f"row {b // 3} col {b % 3}" if b >= 0 else "-"
        click.echo(f"{i:>5} {p[0]:9.2f} {p[1]:9.2f} {p[2]:9.2f}  {block}")
    for k, v in cov.row(0).items():
        click.echo(f"{k}: {v}")
    if placed is not None:
        click.echo(placed_text(placed, error))


def register(main: click.Group) -> None:
    main.add_command(simulate_cmd)
