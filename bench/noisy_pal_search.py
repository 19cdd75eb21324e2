"""PAL's noisy search alone, on an exact model: how far the default profile's anytime search
(eight carried chains, the library, the chains' finds ranked on fresh walks) gets in N
punctuations when the model is the robot's own table and the step noise is known, for a given
``noisy_search_scale`` and walks per turn cycle. What a noisy PAL run can reach once its model
is right; the run's own figures add the model's errors on top.

Each punctuation's best turn cycle (the one PAL would test first) is measured by its mean over
``--judge-walks`` fresh noisy walks of the table (one fixed set for every punctuation and
setting, drawn from seed 12345), so settings are compared on the same walks.

The library is the project's less the robot's own sweeps (a robot nobody has searched) unless
``--shapes`` names one; ``--sharp-only`` leaves out the robust sweeps, the starts a noise-free
search gets.

Example (docs/results.md, "Step noise"; about 2 minutes a seed at scale 2 on one core):
``python bench/noisy_pal_search.py --robot shifted --step-noise 0.3,1 --seeds 0-3 --jobs 2``
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

from pac_host.coverage import START_POSE, format_turn_cycle
from pac_host.coverage.noisy import NoisyWalks, draw_normals
from pac_host.learning import anytime_search, profiles
from pac_host.learning.anytime_search import _AnytimeSearch
from pac_host.learning.config import PALConfig
from pac_host.learning.state import initial_state
from pac_host.model.best_known import builtin_table
from pac_host.model.step_noise import parse_step_noise
from pac_host.search import shapes

JUDGE_SEED = 12345


def one_seed(robot: str, level: str, seed: int, punctuations: int, scale: int, walks: int,
             judge_walks: int, library: str) -> dict:
    """One seed's search: the judged mean of each punctuation's best, and its final sweep."""
    anytime_search.SEARCH_WALKS = walks  # this process's search walks (a worker's own copy)
    table, noise = builtin_table(robot), parse_step_noise(level)
    cfg = replace(profiles.apply("default", PALConfig()), noisy_search_scale=scale,
                  shapes=library)
    rng = np.random.default_rng(seed)
    state = initial_state(table, rng, cfg)
    state.step_noise = noise
    judge_rng = np.random.default_rng(JUDGE_SEED)
    normals = draw_normals(judge_rng, judge_walks, cfg.budget)
    error = cfg.placement_error()
    starts = START_POSE if error is None else error.draw(judge_walks, judge_rng)
    judge = NoisyWalks(table.rows, noise, normals, cfg.budget, table.effects, starts)
    models = np.stack([table.rows, table.rows])
    t0, means = time.perf_counter(), []
    for _ in range(punctuations):
        search = _AnytimeSearch(state, np.random.default_rng(rng.integers(2**63)), cfg)
        search.on_corrected(models, table.effects, state.cga_pop[0], noise)
        state.cga_pop, state.search = search.pop, search.chain
        means.append(round(float(judge.figures(search.pop[:1])[2].mean()), 2))
    return {"seed": seed, "means": means, "final": format_turn_cycle(state.cga_pop[0]),
            "seconds": round(time.perf_counter() - t0, 1)}


def seeds_of(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="shifted", help="a built-in robot")
    ap.add_argument("--step-noise", default="0.3,1")
    ap.add_argument("--seeds", default="0-3", help="A-B or one seed")
    ap.add_argument("--punctuations", type=int, default=25)
    ap.add_argument("--scale", type=int, default=profiles.NOISY_SEARCH_SCALE)
    ap.add_argument("--walks", type=int, default=anytime_search.SEARCH_WALKS)
    ap.add_argument("--judge-walks", type=int, default=2000)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--shapes", default=None,
                    help="the library of good sweeps (default: the project's less the sweeps "
                         "found on the robot)")
    ap.add_argument("--sharp-only", action="store_true",
                    help="leave out the library's robust sweeps (those found with step noise)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        library = args.shapes
        if library is None or args.sharp_only:
            chosen = (shapes.load(library) if library is not None  # the search on a robot
                      else shapes.load("builtin").without(args.robot))  # nobody has searched
            chosen = chosen.sharp() if args.sharp_only else chosen
            library = str(chosen.save(Path(tmp) / "library.json"))
        jobs = [(args.robot, args.step_noise, s, args.punctuations, args.scale, args.walks,
                 args.judge_walks, library) for s in seeds_of(args.seeds)]
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(one_seed, *zip(*jobs, strict=True)))
    finals = [r["means"][-1] for r in results]
    print(json.dumps({"robot": args.robot, "step_noise": args.step_noise, "scale": args.scale,
                      "walks": args.walks, "runs": results,
                      "final_mean": round(float(np.mean(finals)), 2)}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
