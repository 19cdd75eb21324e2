"""`pac-host diagnose`: why does the robot not do what the model says?"""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from pac_host import limits
from pac_host.cli.options import Bounded, effects_module_option
from pac_host.diagnose import diagnose, read_runs, split_runs
from pac_host.diagnose.report import summary, to_json, write_json, write_plots
from pac_host.errors import InputError
from pac_host.model import resolve_table, save_table


@click.command("diagnose")
@click.option("--model", "model_spec", required=True, metavar="measured|shifted|TABLE.json",
              help="The model: a built-in table name or a pac-gait-table/1 file.")
@click.option("--runs", "runs_path", required=True, type=click.Path(dir_okay=False),
              help="Observed runs, JSON Lines (one run per line).")
@click.option("--holdout-fraction", default=None, type=float,
              help="Share of the runs (whole runs, chosen by --seed) held out from fitting "
                   "[default: 0.3].")
@click.option("--holdout", "holdout_path", type=click.Path(dir_okay=False),
              help="Held-out runs in their own file; then every run of --runs is for fitting.")
@click.option("--seed", default=0, show_default=True, type=Bounded(limits.SEED),
              help="Seed of the split and the bootstrap.")
@click.option("--library", default=None, metavar="NAME,...",
              help="Try only these effects (default: all of the library, with the effects "
                   "of --effects-module).")
@effects_module_option()
@click.option("--json", "json_path", type=click.Path(dir_okay=False),
              help="Write the pac-diagnosis/1 report here.")
@click.option("--plots", "plots_dir", type=click.Path(file_okay=False),
              help="Write PNG plots into this directory.")
@click.option("--write-model", "model_out", type=click.Path(dir_okay=False),
              help="Write the model with the selected effects as pac-gait-table/1.")
def diagnose_cmd(model_spec, runs_path, holdout_fraction, holdout_path, seed, library, json_path,
                 plots_dir, model_out) -> None:
    """Diagnose the gap between a model and observed runs.

    Shows where the one-step residuals lie (by gait cycle, component, context), which effects
    of the library the gap is consistent with (forward selection judged on held-out runs),
    and how far the held-out gap shrinks once they are modelled.
    """
    table = resolve_table(model_spec)
    runs = read_runs(runs_path)
    rng = np.random.default_rng(seed)
    if holdout_path:
        if holdout_fraction is not None:
            raise InputError("give --holdout or --holdout-fraction, not both")
        fit_runs, hold_runs = runs, read_runs(holdout_path)
    else:
        holdout_fraction = 0.3 if holdout_fraction is None else holdout_fraction
        fit_runs, hold_runs = split_runs(runs, holdout_fraction, rng)
    lib = None
    if library is not None:
        lib = [s.strip() for s in library.split(",") if s.strip()]
        if not lib:
            raise InputError("--library: give at least one effect name")
    # the order the runs were recorded in: --runs as given, then --holdout
    order = [r.run_id for r in runs] + ([r.run_id for r in hold_runs] if holdout_path else [])
    d = diagnose(table, fit_runs, hold_runs, rng, lib, order=order)
    meta = {"inputs": {"model": model_spec, "runs": Path(runs_path).name,
                       "holdout": Path(holdout_path).name if holdout_path else None,
                       "holdout_fraction": None if holdout_path else holdout_fraction,
                       "seed": seed, "library": lib}}
    for line in summary(d):
        click.echo(line)
    if json_path:
        write_json(to_json(d, meta), json_path)
        click.echo(f"wrote {json_path}")
    if plots_dir:
        for p in write_plots(d, plots_dir):
            click.echo(f"wrote {p}")
    if model_out:
        save_table(d.corrected_table(), model_out)
        click.echo(f"wrote {model_out} ({len(d.corrected_table().effects)} effects)")


def register(main: click.Group) -> None:
    main.add_command(diagnose_cmd)



