"""Run a sweep's cells on an executor, each cell's results on disk as soon as it finishes.

Each cell is one :func:`~pac_host.experiments.experiment.run_experiment` in ``OUT/cells/ID/`` (its
``summary.json``, ``log.jsonl``, ``optimum.json``); its tasks (optimum runs, starting
populations, one PAL run per seed and method) go to the executor, several cells at a time so
a cluster's workers stay busy between one cell's stages. Every task carries its own seed, so
the results do not depend on the executor, on the order cells finish in, or on a worker dying
(its tasks are rerun). ``results.csv``/``results.json`` are rewritten as each cell lands, so
they always hold every finished cell; an interrupted sweep resumes: finished cells are
skipped, unfinished ones keep their finished PAL runs.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait
from pathlib import Path

from pac_host.errors import InputError
from pac_host.experiments.executors import Executor
from pac_host.experiments.experiment import run_experiment
from pac_host.experiments.sweep.results import cell_rows, finish_rows, write_tables
from pac_host.experiments.sweep.spec import Cell
from pac_host.files import write_atomic

CONFIG = "sweep.json"  # the sweep a run started with (cli/sweep.py's --resume checks it)
# progress(event, cell, cells done, cells in all, seconds): event "skipped" or "finished"
Progress = Callable[[str, Cell, int, int, float], None]


def setting_keys(cells: list[Cell]) -> list[str]:
    """Every setting any cell sets, in the order they first appear."""
    keys: list[str] = []
    for c in cells:
        keys += [k for k in c.settings if k not in keys]
    return keys


def varying_keys(cells: list[Cell]) -> list[str]:
    """The settings whose values differ between cells: what tells the cells apart."""
    return [k for k in setting_keys(cells)
            if len({json.dumps(c.settings.get(k)) for c in cells}) > 1]


def cell_dir(out_dir: Path, cell: Cell) -> Path:
    return out_dir / "cells" / cell.id


def run_sweep(cells: list[Cell], out_dir: Path, engine: Executor, resume: bool = False,
              progress: Progress | None = None, config: dict | None = None) -> dict:
    """Run every cell not yet finished in ``out_dir``; returns the results document.
    ``config``: written to OUT/sweep.json when a sweep starts (what a resume checks)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    started = (out_dir / "cells").exists() and any((out_dir / "cells").iterdir())
    if started and not resume:
        raise InputError(f"{out_dir} holds a sweep: use --resume to continue it, or another "
                         "--out")
    if config is not None and not resume:
        write_atomic(out_dir / CONFIG, json.dumps(config, indent=1) + "\n")
    keys = setting_keys(cells)
    by_id = {c.id: c for c in cells}
    rows: list[dict] = []
    lock = threading.Lock()
    done = [0]

    def landed(event: str, cell: Cell, summary: dict, seconds: float) -> None:
        with lock:
            rows.extend(cell_rows(cell, summary))
            write_tables(out_dir, cells, finish_rows(by_id, rows), keys)
            done[0] += 1
            if progress:
                progress(event, cell, done[0], len(cells), seconds)

    def run_cell(cell: Cell) -> None:
        t0 = time.perf_counter()
        d = cell_dir(out_dir, cell)
        d.mkdir(parents=True, exist_ok=True)
        write_atomic(d / "cell.json", json.dumps(
            {"index": cell.index, "id": cell.id, "settings": cell.settings}, indent=1) + "\n")
        summary = run_experiment(d, cell.config, cell.model, cell.actual, engine, resume)
        landed("finished", cell, summary, time.perf_counter() - t0)

    todo = []
    for cell in cells:
        summary_path = cell_dir(out_dir, cell) / "summary.json"
        if resume and summary_path.exists():
            landed("skipped", cell, json.loads(summary_path.read_text()), 0.0)
        else:
            todo.append(cell)
    in_flight = min(len(todo), max(2, 2 * engine.slots)) if engine.slots > 1 else 1
    if in_flight <= 1:
        for cell in todo:
            run_cell(cell)
    elif todo:
        pool = ThreadPoolExecutor(max_workers=in_flight, thread_name_prefix="sweep-cell")
        futs = [pool.submit(run_cell, c) for c in todo]
        try:
            finished, _ = wait(futs, return_when=FIRST_EXCEPTION)
            for f in finished:
                f.result()
        finally:
            pool.shutdown(wait=False, cancel_futures=True)
    with lock:
        write_tables(out_dir, cells, finish_rows(by_id, rows), keys)
    return json.loads((out_dir / "results.json").read_text())
