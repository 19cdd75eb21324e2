"""`pac-host sweep`: many experiments over a grid of settings, locally or on a Dask cluster."""

from __future__ import annotations

import time
from pathlib import Path

import click

from pac_host.cli.cluster_options import scheduler_options
from pac_host.cli.progress import Progress, quiet_option
from pac_host.cli.resume import saved_doc
from pac_host.errors import FileFault, InputError, PacError, with_hint
from pac_host.experiments.executors import Executor, InProcess, dask_executor, make_executor
from pac_host.experiments.sweep import load_sweep, run_sweep, varying_keys
from pac_host.experiments.sweep.runner import CONFIG


def _local(jobs: int) -> Executor:
    """One job runs in this process; more start a Dask LocalCluster of that many workers."""
    return InProcess() if jobs <= 1 else dask_executor(None, jobs)


@click.command("sweep")
@click.argument("sweep_file", metavar="SWEEP.toml",
                type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory for results.csv, results.json, the plots and cells/ID/.")
@click.option("--jobs", default=1, show_default=True, type=click.IntRange(1, 256),
              help="Workers of a local Dask cluster (1: run in this process); results do not "
                   "depend on it.")
@scheduler_options
@click.option("--resume", is_flag=True, help="Continue an interrupted sweep in --out: finished "
              "cells are skipped; SWEEP.toml must give the cells it was started with "
              "(OUT/sweep.json).")
@quiet_option
def sweep_cmd(sweep_file, out_dir, jobs, scheduler, connect_timeout, resume, quiet) -> None:
    """Run `experiment` for every cell of a grid of settings.

    SWEEP.toml has [settings] (every cell's), [grid] (a list of values per setting: every
    combination is a cell) and [[cells]] (explicit cells). A setting is any of experiment's:
    methods, model_fitness, actual, effects, budget, generations, seeds, the GA settings
    (cga_population, pal.cga.bit_mutation_rate, ...); and profile (paper, default, or none,
    the default: the configuration's own), which a cell's other settings apply on top of and
    every cell records.

    Writes OUT/cells/ID/ (each cell's experiment, as soon as it finishes), OUT/results.csv and
    OUT/results.json (one row per cell, seed and method) and OUT/final_coverage.png,
    OUT/mean_coverage.png.

    Progress goes to stderr (a line per cell through a pipe); --quiet silences it.

    Example: pac-host sweep sweep.toml --out out/sweep --jobs 2
    """
    cells = load_sweep(sweep_file)
    saved = {"format": CONFIG_FORMAT, "sweep_file": str(Path(sweep_file).resolve()),
             "cells": [c.id for c in cells]}
    if resume:
        _check_resume(out_dir, sweep_file, saved)
    keys = varying_keys(cells)
    t0 = time.perf_counter()

    again = f"`pac-host sweep {sweep_file} --out {out_dir} --resume` continues it"
    try:
        with Progress("sweep", quiet, {"cells": "cells"}) as bar, \
                make_executor(jobs, scheduler, connect_timeout, local=_local) as engine:
            def progress(event, cell, done, total, seconds):
                what = "already done" if event == "skipped" else f"done in {seconds:.1f} s"
                bar("cells", done, total, f"{cell.id} ({cell.label(keys)}): {what}")

            bar("cells", 0, len(cells))
            doc = run_sweep(cells, out_dir, engine, resume, progress, config=saved)
    except FileFault as e:  # a full disk: the cells finished are kept
        if not (Path(out_dir) / CONFIG).exists():
            raise
        raise with_hint(e, f"{again} (the cells finished are kept)") from None
    minutes = (time.perf_counter() - t0) / 60
    from pac_host.experiments.sweep.plots import sweep_plots  # matplotlib: not for --help

    try:
        plots = sweep_plots(cells, doc["rows"], keys, out_dir)
    except PacError as e:  # the results are whole: only the plots are missing
        raise with_hint(e, f"the results are in {Path(out_dir) / 'results.csv'}; {again} "
                           "and draws the plots again") from None
    click.echo(f"{len(cells)} cells, {len(doc['rows'])} rows in {minutes * 60:.1f} s "
               f"({len(cells) / max(minutes, 1e-9):.2f} cells per minute)")
    click.echo(f"results: {out_dir / 'results.csv'}, {out_dir / 'results.json'}")
    click.echo("plots: " + ", ".join(str(p) for p in plots))


CONFIG_FORMAT = "pac-sweep-config/1"


def _check_resume(out_dir: Path, sweep_file: Path, now: dict) -> None:
    """--resume: OUT must hold a sweep started from the same cells (each cell's id is a hash
    of all its results depend on), or it is refused, naming SWEEP.toml."""
    doc = saved_doc(out_dir, CONFIG, CONFIG_FORMAT, "a sweep run")
    was = doc.get("cells") or []
    if now["cells"] != was:
        other = len(set(now["cells"]) ^ set(was))
        raise InputError(f"SWEEP.toml {sweep_file} differs from the saved run's "
                         f"({doc.get('sweep_file')}: {len(was)} cells; {other} cells differ "
                         "between them); resume takes the saved sweep: give its file as it "
                         "was, or start a new --out")
    click.echo(f"resuming the saved sweep of {len(was)} cells (SWEEP.toml gives the same "
               "cells)")


def register(main: click.Group) -> None:
    main.add_command(sweep_cmd)
