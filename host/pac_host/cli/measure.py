"""`pac-host measure`: walk each gait cycle id and rebuild the gait table from observations."""

from __future__ import annotations

import json
from pathlib import Path

import click

from pac_host import limits
from pac_host.cli.link_options import ask, confirm, emulator_options, link_options
from pac_host.cli.options import Bounded
from pac_host.cli.progress import Progress, quiet_option
from pac_host.model.table import COMPONENTS, resolve_table, save_table
from pac_host.robot.connect import connect
from pac_host.robot.linked import AppendLog
from pac_host.robot.measure import (
    MEASURE_START,
    MeasureConfig,
    differences,
    measure,
    measured_table,
    parse_ids,
)
from pac_host.robot.recovery import Recovery, describe_counts


def _pose(text: str) -> tuple[float, float, float]:
    from pac_host.errors import InputError

    try:
        x, y, h = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--start: expected X,Y,H, got {text!r}") from None
    return x, y, h


@click.command("measure")
@link_options
@click.option("--ids", default="0-31", show_default=True, help="Gait cycle ids, e.g. 0-3,12.")
@click.option("--repeats", default=5, show_default=True, type=Bounded(limits.REPEATS),
              help="Placements per id (each a STEP of --cycles gait cycles).")
@click.option("--cycles", default=1, show_default=True, type=int,
              help="Gait cycles per placement.")
@click.option("--start", default=",".join(f"{v:g}" for v in MEASURE_START), show_default=True,
              metavar="X,Y,H", help="The known pose each repeat starts from.")
@click.option("--seed", default=0, show_default=True, type=Bounded(limits.SEED),
              help="Seeds the emulator's per-run tracker noise.")
@click.option("--table", "table_spec", default="measured", show_default=True,
              metavar="measured|shifted|FILE", help="The current table to compare with.")
@click.option("--out", "out_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The measured pac-gait-table/1 file to write.")
@quiet_option
def measure_cmd(ids, repeats, cycles, start, seed, table_spec, out_path, port, observer_spec,
                placer, quiet, **sim) -> None:
    """Walk each gait cycle id REPEATS times from a known pose and fit its (F, T, dH).

    Writes OUT (pac-gait-table/1: the current table with the measured ids replaced),
    OUT.measure.json (per id: mean, standard deviation, standard error, n, and the difference
    from the current table), OUT.png (the differences with 3-standard-error whiskers),
    OUT.observations.jsonl (every observation) and OUT.runs.jsonl (the observed runs). Prints
    each id's measurement and its difference from the current table. Progress goes to stderr
    (a line per id through a pipe); --quiet silences it.
    """
    cfg = MeasureConfig(parse_ids(ids), repeats, cycles, _pose(start), seed)
    cfg.check()
    current = resolve_table(table_spec)
    emu = emulator_options(sim, port)
    side = {k: out_path.with_name(out_path.stem + k) for k in
            (".measure.json", ".png", ".observations.jsonl", ".runs.jsonl")}
    out_path.parent.mkdir(parents=True, exist_ok=True)
    for k in (".observations.jsonl", ".runs.jsonl"):
        side[k].unlink(missing_ok=True)
    with connect(port, observer_spec, emu, ask, confirm, "pose", placer) as conn:
        click.echo(f"robot: {conn.description}; observer: {conn.observer.name}")
        recovery = Recovery()
        with Progress("measure", quiet, {"gait ids": "ids"}) as bar:
            bar("gait ids", 0, len(cfg.ids))
            fits = measure(conn, cfg, AppendLog(side[".observations.jsonl"]),
                           AppendLog(side[".runs.jsonl"]),
                           lambda gait, done, total: bar("gait ids", done, total, f"id {gait}"),
                           recovery=recovery)
    table = measured_table(current, fits, out_path.stem)
    save_table(table, out_path)
    diffs = differences(current, fits)
    side[".measure.json"].write_text(json.dumps({
        "format": "pac-gait-measurement/1", "compared_with": current.name,
        "repeats": repeats, "cycles": cycles, "start": list(cfg.start),
        "fits": [f.to_json() for f in fits], "differences": diffs,
        "recovery": recovery.counts()}, indent=1) + "\n")
    import numpy as np

    from pac_host.robot.measure_plots import table_differences

    table_differences([f.gait for f in fits], np.array([[d[c] for c in COMPONENTS] for d in diffs]),
                      np.array([f.se for f in fits]), side[".png"],
                      f"{out_path.stem} minus {current.name}")
    click.echo(f"{'id':>3} " + " ".join(f"{c + ' +- se':>15}" for c in COMPONENTS)
               + "   difference from " + current.name)
    flagged = 0
    for f, d in zip(fits, diffs, strict=True):
        vals = " ".join(f"{f.mean[j]:8.2f} +-{f.se[j]:5.2f}" for j in range(3))
        big = [c for c in COMPONENTS if abs(d[f"z_{c}"]) > 3]
        flagged += bool(big)
        note = "  <- " + ",".join(big) + " beyond 3 se" if big else ""
        click.echo(f"{f.gait:>3} {vals}   " + " ".join(f"{d[c]:+6.2f}" for c in COMPONENTS)
                   + note)
    click.echo(f"{flagged} of {len(fits)} ids differ from {current.name} by more than 3 "
               f"standard errors; wrote {out_path}, {side['.measure.json'].name}, "
               f"{side['.png'].name}")
    click.echo(describe_counts(recovery.counts()))


def register(main: click.Group) -> None:
    main.add_command(measure_cmd)
