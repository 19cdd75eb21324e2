"""The turn-cycle search: `pac-host optimize` against the best known fitness, and anytime PAL.

- ``optimize``: SEEDS seeds x SECONDS s each, one core, on the shifted and the measured table
  (the search alone, without the library of sweeps);
  the best fitness per seed, the seconds to reach the best known (median over seeds), and a plot
  of best fitness against seconds (median and range over seeds). Target (shifted): fitness 34
  or better on at least 9 of 10 seeds.
- ``experiment``: the 30-seed, three-method experiment with the default profile (anytime PAL,
  its search budget per punctuation) and --jobs 2: wall time (target <= 20 minutes) and the
  oracle's final fitness against the best known (target: >= 95% on at least 27 of 30 seeds).

Usage: ``python bench/run.py --only search`` (about 45 minutes on an idle 2-core machine;
``--quick`` is a smoke run).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from pac_host.model import measured_table, shifted_table
from pac_host.plots import optimize_progress
from pac_host.search.optimize import OptimizeConfig, best_over_time, optimize

HERE = Path(__file__).resolve().parent
BEST_KNOWN = json.loads((HERE / "best_known.json").read_text())  # raised to what runs find


def optimize_runs(table, seeds: int, seconds: float, plot: Path) -> dict:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core
    runs = []
    for seed in range(seeds):
        r = optimize(table.rows, OptimizeConfig(seconds=seconds, seed=seed, shapes="none"))
        runs.append({"seed": seed, "fitness": r["fitness"], "turn_cycle": r["turn_cycle"],
                     "evaluations": r["evaluations"], "growth": best_over_time(r["chains"])})
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, set(range(os.cpu_count() or 1)))
    known = BEST_KNOWN.get(table.name, {}).get("fitness", 0)
    best = max([r["fitness"] for r in runs] + [known])
    reach = [next((t for t, f in r["growth"] if f >= best), None) for r in runs]
    optimize_progress([r["growth"] for r in runs], plot,
                      f"optimize on {table.name}: {seeds} seeds, {seconds:.0f} s each, one core")
    return {"best_known": best, "seconds": seconds,
            "fitness": [r["fitness"] for r in runs],
            "reached_best_known": sum(t is not None for t in reach),
            "median_seconds_to_best_known": (float(np.median([t for t in reach if t is not None]))
                                             if any(t is not None for t in reach) else None),
            "evaluations_per_second": round(float(np.mean([r["evaluations"] for r in runs]))
                                            / seconds),
            "plot": str(plot), "runs": runs}


def experiment(quick: bool, best_known: int) -> dict:
    seeds, gens = (2, 120) if quick else (30, 1000)
    with tempfile.TemporaryDirectory() as d:
        cmd = [sys.executable, "-m", "pac_host.cli", "experiment", "--seeds", str(seeds),
               "--generations", str(gens), "--methods", "full,partial,oracle", "--jobs", "2",
               "--out", d]
        t = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        wall = time.perf_counter() - t
        summary = json.loads((Path(d) / "summary.json").read_text())
    best = max(best_known, summary["optimum"])
    oracle = [r["coverage"][-1] for r in summary["runs"] if r["method"] == "oracle"]
    return {"wall_s": round(wall, 1), "seeds": seeds, "generations": gens,
            "search_evaluations_per_punctuation": summary["pal_config"]["search_evaluations"],
            "optimum": summary["optimum"], "best_known": best,
            "oracle_final": oracle,
            "oracle_at_95_percent": sum(f >= 0.95 * best for f in oracle),
            "methods": {m: {k: v for k, v in s.items() if k != "mean_coverage"}
                        for m, s in summary["comparison"]["methods"].items()}}


def run(quick: bool = False) -> dict:
    seeds, seconds = (2, 5.0) if quick else (10, 60.0)
    out_dir = HERE / "results"
    res = {"optimize": {
        name: optimize_runs(table, seeds, seconds, out_dir / f"optimize_{name}.png")
        for name, table in (("shifted", shifted_table()), ("measured", measured_table()))}}
    shifted = res["optimize"]["shifted"]
    res["experiment"] = experiment(quick, shifted["best_known"])
    exp = res["experiment"]
    res["targets"] = {
        "optimize_shifted_34_on_9_of_10": {
            "value": sum(f >= 34 for f in shifted["fitness"]), "target": ">= 9 of 10",
            "met": sum(f >= 34 for f in shifted["fitness"]) >= 0.9 * seeds},
        "oracle_95_percent_on_27_of_30": {
            "value": exp["oracle_at_95_percent"], "target": ">= 27 of 30",
            "met": exp["oracle_at_95_percent"] >= 0.9 * exp["seeds"]},
        "experiment_30x3_jobs2_s": {"value": exp["wall_s"], "target": "<= 1200",
                                    "met": exp["wall_s"] <= 1200},
    }
    return res
