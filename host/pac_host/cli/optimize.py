"""`pac-host optimize`: search hard for the best turn cycle on one model."""

from __future__ import annotations

import json
from pathlib import Path

import click

from pac_host import limits
from pac_host.cli.options import (
    Bounded,
    effect_option,
    kick_length_cost_option,
    load_with_effects,
    placed_text,
    placement_option,
    shapes_option,
    shorten_after_option,
    table_option,
)
from pac_host.cli.progress import Progress, quiet_option
from pac_host.coverage import DEFAULT_BUDGET
from pac_host.coverage.placement import parse_placement
from pac_host.errors import InputError
from pac_host.files import write_atomic
from pac_host.search.local import SAMPLE
from pac_host.search.optimize import Interrupted, OptimizeConfig, best_over_time, optimize
from pac_host.search.shorten import SHORTEN_AFTER


@click.command("optimize")
@table_option(default="shifted")
@effect_option()
@click.option("--budget", default=DEFAULT_BUDGET, show_default=True, type=Bounded(limits.BUDGET),
              help="Gait cycles per walk.")
@click.option("--seconds", type=float,
              help="Stop the search after this many seconds (wall time; its clock starts once "
                   "the compiled simulator is loaded). Ctrl-C stops it too, printing and "
                   "writing the best found so far.")
@click.option("--evaluations", type=Bounded(limits.EVALUATIONS),
              help="Stop after this many coverage evaluations (reproducible).")
@click.option("--chains", default=1, show_default=True, type=Bounded(limits.CHAINS),
              help="Independent search chains; the result depends on the seed and the chains, "
                   "not on --jobs.")
@click.option("--sample", default=SAMPLE, show_default=True,
              type=click.FloatRange(0, 1, min_open=True),
              help="Share of a gene's 2,016 changes a climb scores each time it looks at the "
                   "gene (1: every change, an exact local optimum).")
@kick_length_cost_option(0.0)
@shorten_after_option(SHORTEN_AFTER)
@placement_option()
@shapes_option("builtin")
@click.option("--seed", default=0, show_default=True, type=Bounded(limits.SEED))
@click.option("--jobs", default=1, show_default=True, type=click.IntRange(1, 64),
              help="Processes running chains side by side.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the result, each chain's progress and the settings here.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path),
              help="Draw the best fitness against seconds to this PNG.")
@quiet_option
def optimize_cmd(table_spec, effect_specs, budget, seconds, evaluations, chains, sample,
                 kick_length_cost, shorten_after, placement, shapes, seed, jobs, json_out,
                 plot, quiet) -> None:
    """Find the best turn cycle on a model: iterated local search with restarts.

    Prints the best turn cycle, its coverage figures (as `simulate` gives them) and how the
    best fitness grew with time. Without --seconds or --evaluations it runs 60 seconds.

    Example: pac-host optimize --table shifted --seconds 60 --seed 3 --json best.json

    With --placement-error every turn cycle costs seven walks (the stencil's start poses).
    Progress goes to stderr (a line per finished chain through a pipe); --quiet silences it.
    """
    if seconds is None and evaluations is None:
        seconds = 60.0
    cfg = OptimizeConfig(budget=budget, seconds=seconds, evaluations=evaluations, chains=chains,
                         seed=seed, sample=sample, placement=parse_placement(placement),
                         shapes=shapes, kick_length_cost=kick_length_cost,
                         shorten_after=shorten_after)
    cfg.check()
    table = load_with_effects(table_spec, effect_specs)
    if json_out is not None and json_out.is_dir():
        raise InputError(f"--json {json_out} is a directory")
    interrupted = False
    try:
        with Progress("optimize", quiet) as progress:
            res = optimize(table.rows, cfg, table.effects, jobs, progress)
    except Interrupted as e:  # Ctrl-C: the best found so far is printed and written
        if e.result is None:
            raise
        res, interrupted = e.result, True
    res["table"] = {"name": table.name, "effects": [e.to_json() for e in table.effects]}
    growth = best_over_time(res["chains"])
    click.echo(f"best turn cycle on {table.name}: {res['turn_cycle']}")
    for k in ("blocks_covered", "blocks_covered_once", "fitness", "repeat_visits"):
        click.echo(f"{k}: {res[k]}")
    if "placed" in res:
        click.echo(f"from the placement stencil: mean fitness {res['stencil_fitness']:.2f}; "
                   + placed_text(res["placed"], cfg.placement))
    click.echo(f"{res['evaluations']} evaluations in {res['seconds']:.1f} s")
    click.echo("best fitness over time: " + ", ".join(f"{f:.3g} at {t:.1f} s" for t, f in growth))
    if json_out is not None:
        write_atomic(json_out, json.dumps(res, indent=1) + "\n")
    if plot is not None:
        from pac_host.plots import optimize_progress

        optimize_progress([growth], plot, f"optimize on {table.name}")
    if interrupted:
        click.echo("pac-host: interrupted: the best found so far is above"
                   + (" and written" if json_out or plot else ""), err=True)
        raise click.exceptions.Exit(130)


def register(main: click.Group) -> None:
    main.add_command(optimize_cmd)
