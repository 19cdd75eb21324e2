"""The default `pac-host evolve` on a noisy emulator: the run a lab user starts (the default
profile against the built-in emulator with step noise), for several seeds, each punctuation's
operational turn cycle (``log.jsonl``'s ``operational``) measured afterwards by its mean over
400 fresh noisy walks of the emulator's robot from the exact start, as ``pac-host simulate
--table ROBOT --turn-cycle TC --step-noise LEVEL --walks 400 --seed 0`` gives it (the same
walks for every punctuation and seed), against the best known: the robot's robust record at
that noise (``pac_host/model/best_known.json``), or ``--best-known`` where that is higher. The
runs' library of sweeps is the built-in one less those found on the robot: a robot nobody has
searched.

Targets (issue): the operational sweep's expected coverage reaches 90% of the best known by a
median of at most 5 punctuations, and ends at 95% or more on at least 9 of 10 seeds.

Usage: ``python bench/bench_noisy_evolve.py [--robot shifted|FILE] [--step-noise 0.3,1]
[--seeds 10|A-B] [--generations 1000] [--parallel 2] [--best-known F] [--quick]`` or
``python bench/run.py --only noisy_evolve`` (the shifted robot at 0.3 cm / 1 deg, 10 seeds of
1000 generations, 26 punctuations (generation 0 and every 40): each seed about 6 minutes, two
side by side, so about 30 minutes on two cores; ``--quick``: 2 seeds of 200 generations, 6
punctuations, about a minute and a half).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from functools import cache
from pathlib import Path

import numpy as np

from pac_host.coverage import DEFAULT_BUDGET, parse_turn_cycle
from pac_host.coverage.walks import walk_many
from pac_host.experiments.experiment import (
    FINAL_TARGET,
    TARGET,
    ExperimentConfig,
    best_known_on,
    punctuations_to,
)
from pac_host.model import load_with_effects
from pac_host.search import shapes

PAC_HOST = Path(sys.executable).parent / "pac-host"
WALKS, WALK_SEED, SHARE, MEDIAN_PUNCTUATIONS = 400, 0, 0.9, 5


def seed_list(text: str | int) -> list[int]:
    """``N`` (seeds 0..N-1) or ``A-B`` (A..B)."""
    a, sep, b = str(text).partition("-")
    return list(range(int(a), int(b) + 1)) if sep else list(range(int(a)))


def best_known(robot: str, step_noise: str, given: float | None) -> dict:
    """The robot's robust record at the noise (if any) or ``given``, whichever is higher, as
    an experiment judges its runs (:func:`pac_host.experiments.experiment.best_known_on`,
    with no optimum of its own)."""
    best = best_known_on(load_with_effects(robot, (), step_noise),
                         ExperimentConfig(best_known=given), optimum=0.0)
    if best["used"] == "optimum":
        raise SystemExit(f"no robust record for {robot} at {step_noise}: give --best-known")
    return best


def expected_coverage(robot: str, step_noise: str):
    """A turn cycle's mean fitness over the fresh noisy walks of ``pac-host simulate``
    (seed 0, from the exact start), cached by its text."""
    table = load_with_effects(robot, (), step_noise)

    @cache
    def mean(turn_cycle: str) -> float:
        figs, _ = walk_many(table.rows, parse_turn_cycle(turn_cycle), WALKS, DEFAULT_BUDGET,
                            table.effects, table.step_noise, np.random.default_rng(WALK_SEED))
        return round(float(figs.fitness.mean()), 2)
    return mean


def evolve(seed: int, out: Path, base: list[str]) -> tuple[int, list[str] | str]:
    """One evolve run: its punctuations' operational turn cycles, or its stderr's last line."""
    cmd = [*base, "--out", str(out / f"seed-{seed}"), "--seed", str(seed)]
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if p.returncode:
        return seed, (p.stderr.strip().splitlines() or [f"exit {p.returncode}"])[-1]
    log = (out / f"seed-{seed}" / "log.jsonl").read_text().splitlines()
    return seed, [json.loads(line)["operational"] for line in log if line.strip()]


def run(quick: bool = False, robot: str = "shifted", step_noise: str = "0.3,1",
        seeds: str | int | None = None, generations: int | None = None, parallel: int = 2,
        given: float | None = None) -> dict:
    chosen = seed_list(seeds or (2 if quick else 10))
    generations = generations or (200 if quick else 1000)
    best = best_known(robot, step_noise, given)
    mean = expected_coverage(robot, step_noise)
    coverage: dict[int, list[float]] = {}
    failed: dict[int, str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        out, library = Path(tmp), Path(tmp) / "library.json"
        # the project's library less the sweeps found on the robot: a robot nobody has searched
        shapes.load("builtin").without(robot).save(library)
        base = [str(PAC_HOST), "evolve", *(["--sim-table", robot] if robot != "shifted" else []),
                "--sim-step-noise", step_noise, "--generations", str(generations), "--quiet",
                "--shapes", str(library)]
        t0 = time.perf_counter()
        with ThreadPoolExecutor(max(1, parallel)) as pool:
            for fut in as_completed([pool.submit(evolve, s, out, base) for s in chosen]):
                seed, res = fut.result()
                if isinstance(res, str):
                    failed[seed] = res
                    print(f"seed {seed}: failed: {res}", file=sys.stderr, flush=True)
                    continue
                coverage[seed] = [mean(tc) for tc in res]
                print(f"seed {seed}: {len(res)} punctuations, expected coverage "
                      f"{coverage[seed][-1] if res else None} at the end "
                      f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
        wall = time.perf_counter() - t0
    fit = best["fitness"]
    done = sorted(coverage)
    finals = {s: round(coverage[s][-1] / fit, 3) if coverage[s] else None for s in done}
    reached = {s: punctuations_to(coverage[s], TARGET * fit) for s in done}
    key = [reached.get(s) or np.inf for s in chosen]  # failed and unreached: never
    median = float(np.median(key))
    ended = sum(f is not None and f >= FINAL_TARGET for f in finals.values())
    return {
        "command": " ".join(["pac-host", *base[1:base.index("--shapes") + 1], "LIBRARY",
                             "--out", "OUT/seed-S", "--seed", "S"]),
        "seconds": round(wall, 1), "seeds": chosen, "best_known": best,
        "figures": f"expected over {WALKS} walks (seed {WALK_SEED})",
        "coverage": {s: coverage[s] for s in done}, "failed": failed,
        "final_over_best_known": finals, "punctuations_to_90": reached,
        "targets": {
            "median_punctuations_to_90": {
                "target": MEDIAN_PUNCTUATIONS, "value": median if np.isfinite(median) else None,
                "met": bool(median <= MEDIAN_PUNCTUATIONS)},
            "ended_at_95": {"target": f">= {SHARE:.0%} of seeds",
                            "value": f"{ended}/{len(chosen)}",
                            "met": ended >= SHARE * len(chosen)}},
    }


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robot", default="shifted")
    ap.add_argument("--step-noise", default="0.3,1")
    ap.add_argument("--seeds", default=None, help="N (seeds 0..N-1) or A-B")
    ap.add_argument("--generations", type=int, default=None)
    ap.add_argument("--parallel", type=int, default=2, help="evolve runs side by side")
    ap.add_argument("--best-known", type=float, default=None)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    print(json.dumps(run(a.quick, a.robot, a.step_noise, a.seeds, a.generations, a.parallel,
                         a.best_known), indent=1))
