"""Sweep benchmark: cells per minute on a Dask LocalCluster of 1 and of 2 worker processes.

The same sweep (a grid of methods and model fitnesses, each cell a small experiment of several
seeds) runs in this process, then on a LocalCluster of 1 worker and of 2 workers; the cluster's
start-up is timed apart from the sweep. Every engine must give the same results table, byte for
byte. The target is the speed-up of 2 workers over 1 on this 2-core machine (ideal 2). Other
work on the machine lowers it: the load average before and after, and the CPU cores the
workers actually got (their CPU seconds over the wall time), say how much it left to the sweep.
"""

from __future__ import annotations

import logging
import os
import tempfile
import time
from pathlib import Path

from pac_host.experiments.executors import WORKER_CONFIG, DaskExecutor, InProcess, dask_executor
from pac_host.experiments.experiment import ExperimentConfig, optimum_run
from pac_host.experiments.sweep import parse_sweep, run_sweep
from pac_host.model import shifted_table


def _spec(quick: bool) -> dict:
    return {
        # the paper's profile: its model GA is where full and partial recombination differ
        "settings": {"profile": "paper", "seeds": 2 if quick else 4,
                     "generations": 80 if quick else 200,
                     "initial_generations": 50 if quick else 200, "optimum_runs": 2,
                     "optimum_generations": 100 if quick else 300, "budget": 200},
        "grid": {"methods": ["full", "partial"], "model_fitness": ["coverage", "steps"]},
    }


def _cpu_seconds(engine) -> float:
    """CPU seconds used so far by the engine's worker processes (this process if none)."""
    if isinstance(engine, DaskExecutor):
        return sum(engine.client.run(time.process_time).values())
    return time.process_time()


def _timed(cells, out: Path, engine) -> tuple[float, float, bytes]:
    """Wall seconds, the cores the workers got on average, and the results table."""
    t0, c0 = time.perf_counter(), _cpu_seconds(engine)
    run_sweep(cells, out, engine)
    wall = time.perf_counter() - t0
    return wall, (_cpu_seconds(engine) - c0) / wall, (out / "results.json").read_bytes()


def _task_cpu(k: int, cfg: ExperimentConfig) -> float:
    """CPU seconds of one CGA run, measured inside the task."""
    t0 = time.process_time()
    optimum_run(shifted_table(), k, cfg)
    return time.process_time() - t0


def task_cpu_seconds(repeats: int) -> dict:
    """One task's CPU time in this process, on a worker of ours, and on a worker with Dask's
    default MALLOC_TRIM_THRESHOLD_ (which turns glibc's adaptive allocator off)."""
    import dask
    from distributed import Client, LocalCluster

    cfg = ExperimentConfig(optimum_generations=300)
    args = [(k, cfg) for k in range(repeats)]
    out = {"in_process": InProcess().map(_task_cpu, args)}
    with dask_executor(None, 1) as engine:
        out["worker"] = engine.map(_task_cpu, args)
    env = dict(os.environ)
    try:  # last: Dask's nanny leaves the variable in this process's environment
        with dask.config.set({k: 65536 for k in WORKER_CONFIG}):
            cluster = LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None,
                                   silence_logs=logging.ERROR)
        with DaskExecutor(Client(cluster), cluster) as d:
            out["worker_dask_default_malloc"] = d.map(_task_cpu, args)
    finally:
        os.environ.clear()
        os.environ.update(env)
    return {k: {"median_s": round(sorted(v)[len(v) // 2], 3),
                "range_s": [round(min(v), 3), round(max(v), 3)]} for k, v in out.items()}


def run(quick: bool) -> dict:
    cells = parse_sweep(_spec(quick))
    res: dict = {"cells": len(cells), "sweep": _spec(quick),
                 "load_average_before": round(os.getloadavg()[0], 2)}
    with tempfile.TemporaryDirectory() as tmp:
        seconds, cores, reference = _timed(cells, Path(tmp) / "in_process", InProcess())
        res["in_process"] = {"seconds": round(seconds, 2), "cores_used": round(cores, 2),
                             "cells_per_minute": round(len(cells) * 60 / seconds, 2)}
        for workers in (1, 2):
            t0 = time.perf_counter()
            engine = dask_executor(None, workers)
            start = time.perf_counter() - t0
            with engine:
                seconds, cores, table = _timed(cells, Path(tmp) / f"workers_{workers}", engine)
            res[f"workers_{workers}"] = {
                "seconds": round(seconds, 2), "cluster_start_s": round(start, 2),
                "cores_used": round(cores, 2),
                "cells_per_minute": round(len(cells) * 60 / seconds, 2),
                "same_results_as_in_process": table == reference}
    res["task_cpu_seconds"] = task_cpu_seconds(3 if quick else 7)
    res["load_average_after"] = round(os.getloadavg()[0], 2)  # other work on the machine
    ratio = res["workers_2"]["cells_per_minute"] / res["workers_1"]["cells_per_minute"]
    res["speedup_2_over_1"] = round(ratio, 3)
    same = all(res[f"workers_{w}"]["same_results_as_in_process"] for w in (1, 2))
    res["targets"] = {
        "speedup_2_workers": {"value": round(ratio, 3), "target": 1.7, "met": ratio >= 1.7},
        "same_results_on_every_engine": {"value": same, "target": True, "met": same},
    }
    return res
