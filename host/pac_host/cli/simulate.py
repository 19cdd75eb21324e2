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
    step_noise_option,
    table_option,
)
from pac_host.cli.progress import Progress
from pac_host.cli.resume import given
from pac_host.coverage import DEFAULT_BUDGET, START_POSE, check_budget, parse_turn_cycle, simulate
from pac_host.coverage.placement import WALKS, parse_placement, placed_fitness, summary
from pac_host.coverage.walks import CHUNK_STEPS, spread, walk_many
from pac_host.errors import InputError

PLOTTED_WALKS = 40  # noisy walks drawn thin on --plot


@click.command("simulate")
@table_option()
@effect_option()
@step_noise_option("Walk the turn cycle --walks times with each gait cycle's move varying by "
                   "these standard deviations, cm on F and T, deg on dH, and report the "
                   "spread of the figures (not given: the table file's, if any).")
@effects_module_option()
@click.option("--turn-cycle", "turn_cycle", required=True, metavar="ID:REPS,...",
              help='Looped genes of gait cycle id (0..31) and repetitions (0..63), '
                   'e.g. "12:14,3:10".')
@click.option("--budget", default=DEFAULT_BUDGET, show_default=True,
              type=Bounded(limits.SIM_BUDGET),
              help="Gait cycles to run.")
@placement_option(help="Also walk the turn cycle from start poses drawn as a hand placement "
                       "with these standard deviations leaves them (none: only the exact start).")
@click.option("--walks", default=WALKS, show_default=True, type=Bounded(limits.WALKS),
              help="With --step-noise or --placement-error: walks (each from a drawn start "
                   "pose, with drawn step noise); refused without either.")
@click.option("--seed", default=0, show_default=True, type=Bounded(limits.SEED),
              help="With --step-noise or --placement-error: seed of the draws.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object on stdout.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path),
              help="Also draw the path on the area to this PNG.")
def simulate_cmd(table_spec, effect_specs, step_noise, turn_cycle, budget, placement, walks,
                 seed, as_json, plot) -> None:
    """Walk a turn cycle from the start pose (45, 30, 90) and score the path.

    Prints the pose after each gait cycle and the coverage figures: blocks covered, blocks
    covered exactly once, the coverage fitness 3R + c, and repeat visits. With
    --placement-error it also walks the turn cycle from --walks start poses drawn as a hand
    placement with those standard deviations leaves them, and gives the fitness's mean, median
    and 10th percentile: how much of the coverage survives putting the robot down by hand.
    With --step-noise (or a table file's step noise) it walks the turn cycle --walks times,
    each gait cycle's move drawn with that noise (and, with --placement-error, each walk from
    a drawn start pose), and gives the mean, median, 10th and 90th percentiles of the fitness
    and of the blocks covered; --plot then draws the walks' paths thin around the noise-free
    one.

    Example: pac-host simulate --table shifted --turn-cycle 12:14,3:10 --placement-error 0.5,1
    """
    table = load_with_effects(table_spec, effect_specs, step_noise)
    genes = parse_turn_cycle(turn_cycle)
    error = parse_placement(placement)
    budget = check_budget(budget)
    noise = table.step_noise
    if given("walks") and noise.is_zero() and error is None:
        raise InputError("--walks: a noise-free walk from the exact start is one walk; give "
                         "--step-noise or --placement-error")
    cov = simulate(table.rows, genes, budget, table.effects, START_POSE, keep_paths=True)
    placed = walked = None
    kept = None
    if not noise.is_zero():
        rng = np.random.default_rng(seed)
        starts = error.draw(walks, rng) if error is not None else None  # placed_fitness's
        # a line per chunk through a pipe, only where the walks take more than a few seconds
        with Progress("simulate", quiet=walks * (budget + 1) <= 10 * CHUNK_STEPS) as progress:
            figs, kept = walk_many(table.rows, genes, walks, budget, table.effects, noise, rng,
                                   starts, PLOTTED_WALKS if plot else 0,
                                   lambda done, total: progress("walks", done, total))
        walked = {"step_noise": noise.to_json(),
                  "placement": error.to_text() if error is not None else None,
                  "seed": seed, "walks": walks, "fitness": spread(figs.fitness),
                  "blocks_covered": spread(figs.blocks_covered)}
    elif error is not None:
        fit = placed_fitness(table.rows, genes, error, walks, np.random.default_rng(seed),
                             budget, table.effects)
        placed = {"placement": error.to_text(), "seed": seed, **summary(fit)}
    poses = cov.poses[0]
    if plot:
        from pac_host.plots import coverage_path

        title = f"{turn_cycle} on {table.name}"
        if walked is not None:
            title += f", {len(kept)} of {walks} walks with step noise {noise.to_text()}"
        coverage_path(poses, cov.blocks[0], plot, title, cov.row(0), kept)
    if as_json:
        doc = {"poses": [[float(v) for v in p] for p in poses], **cov.row(0)}
        if placed is not None:
            doc["placed"] = placed
        if walked is not None:
            doc["walked"] = walked
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
    if walked is not None:
        click.echo(_walked_text(walked))


def _walked_text(walked: dict) -> str:
    """The spread of the noisy walks' figures, in one line."""
    def figure(d: dict) -> str:
        return (f"mean {d['mean']}, median {d['median']:g}, 10th percentile {d['p10']:g}, "
                f"90th percentile {d['p90']:g}")
    sd = walked["step_noise"]
    noise = (f"{sd['F']:g} cm F, {sd['T']:g} cm T, {sd['dH']:g} deg dH" if "F" in sd
             else "per-cycle deviations")
    where = (f", start poses drawn at {walked['placement']}" if walked["placement"] else "")
    return (f"{walked['walks']} walks with step noise {noise}{where} (seed {walked['seed']}): "
            f"fitness {figure(walked['fitness'])}; blocks covered "
            f"{figure(walked['blocks_covered'])}")


def register(main: click.Group) -> None:
    main.add_command(simulate_cmd)
