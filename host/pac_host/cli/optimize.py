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
    step_noise_option,
    table_option,
)
from pac_host.cli.progress import Progress, quiet_option
from pac_host.coverage import DEFAULT_BUDGET
from pac_host.coverage.placement import parse_placement
from pac_host.errors import InputError
from pac_host.files import write_atomic
from pac_host.search.local import SAMPLE
from pac_host.search.optimize import (
    WALKS_DEFAULT,
    Interrupted,
    OptimizeConfig,
    best_over_time,
    optimize,
)
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
@step_noise_option("Search for what a robot whose every gait cycle varies by these deviations "
                   "(cm on F and T, deg on dH) delivers: each turn cycle is scored by its mean "
                   "fitness over --walks noisy walks with common random numbers (not given: the "
                   "table file's step noise, none for a built-in table). The result is measured "
                   "on 400 fresh walks.")
@click.option("--walks", type=int, default=None,
              help=f"With step noise: noisy walks each turn cycle is scored over "
                   f"[default: {WALKS_DEFAULT}].")
@click.option("--quantile", type=float, default=None,
              help="With step noise: rank turn cycles by this quantile of their walks' fitness "
                   "(e.g. 0.1 to cover the bad days) instead of the mean.")
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
                 kick_length_cost, shorten_after, placement, step_noise, walks, quantile, shapes,
                 seed, jobs, json_out, plot, quiet) -> None:
    """Find the best turn cycle on a model: iterated local search with restarts.

    Prints the best turn cycle, its coverage figures (as `simulate` gives them) and how the
    best fitness grew with time. Without --seconds or --evaluations it runs 60 seconds.

    Example: pac-host optimize --table shifted --seconds 60 --seed 3 --json best.json

    With --placement-error every turn cycle costs seven walks (the stencil's start poses).
    With --step-noise it costs --walks (from start poses drawn with the placement error, if
    given), and the result's mean fitness over 400 fresh noisy walks is printed with its 95%
    interval.
    Progress goes to stderr (a line per finished chain through a pipe); --quiet silences it.
    """
    if seconds is None and evaluations is None:
        seconds = 60.0
    table = load_with_effects(table_spec, effect_specs, step_noise)
    noise = None if table.step_noise.is_zero() else table.step_noise
    if noise is None and (walks is not None or quantile is not None):
        raise InputError("--walks and --quantile score noisy walks: give --step-noise CM,DEG")
    cfg = OptimizeConfig(budget=budget, seconds=seconds, evaluations=evaluations, chains=chains,
                         seed=seed, sample=sample, placement=parse_placement(placement),
                         shapes=shapes, kick_length_cost=kick_length_cost,
                         shorten_after=shorten_after, step_noise=noise,
                         walks=WALKS_DEFAULT if walks is None else walks, quantile=quantile)
    cfg.check()
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
    if "fresh" in res:
        click.echo(fresh_text(res))
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


def fresh_text(res: dict) -> str:
    """How optimize prints a noisy search's result: its figures on fresh noisy walks."""
    f, q = res["fresh"], res["quantile"]
    lo, hi = f["ci95"]
    noise = res["step_noise"]
    what = "mean" if q is None else f"{q:g} quantile"
    return (f"with step noise {noise['F']:g},{noise['dH']:g}" if "F" in noise
            else "with step noise per gait cycle") + (
        f": mean fitness {f['mean']:.2f} over {f['walks']} fresh noisy walks (95% interval "
        f"{lo:.2f}-{hi:.2f}; median {f['median']:g}, 10th percentile {f['p10']:g}"
        + ("" if q is None else f", {q:g} quantile {f['quantile_fitness']:g}")
        + f"); the search's {what} over its {res['walks']} walks "
        f"{res['search_best_fitness']:.2f}; noise-free fitness {res['fitness']}")


def register(main: click.Group) -> None:
    main.add_command(optimize_cmd)
