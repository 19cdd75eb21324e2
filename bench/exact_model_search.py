"""Where a learning run's search stops once its model is exact: the search's reach, not the model's.

Given a ``bench_learning.py`` log of one robot, reports for one method's runs (``--method``,
the recombination the log names them by) per seed the punctuation
(1-based, as the bench counts) from which every row of the model equals the robot's, and the
final operational fitness. Then, on the robot's exact table and from the library less the
sweeps found on that robot (as the bench gives it), two measures of what a search can reach:

- ``pac-host optimize`` with eight chains at each budget of ``--budgets`` (total evaluations)
  and each kick size of ``--kick-genes`` (genes a kick re-draws), seeds 0 ..
  ``--optimize-seeds`` - 1;
- every two-point crossover of the runs' final turn cycles (those below ``--below``, so a rare
  find is not its own parent), scored, and the best ``--climb`` of them climbed to a local
  optimum: whether the runs' finds combine into a better sweep.

Example (docs/explanation/learning.md, "noisy_rows misses the 95% target against its new best
known"):
``python bench/exact_model_search.py --robot noisy_rows --log
out/bench-learning/noisy_rows/default/log.jsonl --below 51``
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np

from pac_host.coverage import fitness_of_search_score, parse_turn_cycle
from pac_host.errors import InputError
from pac_host.experiments.experiment import read_complete_runs
from pac_host.search import shapes
from pac_host.search.local import Objective, climb
from pac_host.search.optimize import OptimizeConfig, optimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_learning import actual_robots  # noqa: E402


def exact_from(records: list[dict], tol: float = 1e-3) -> int | None:
    """The first punctuation (1-based) from which every row's error stays within ``tol``
    (None: not exact at the end)."""
    def worst(r: dict) -> float:
        return max(max(abs(e["F"]), abs(e["T"]), abs(e["dH"])) for e in r["model_error"])
    errs = [worst(r) for r in records]
    return next((i + 1 for i in range(len(errs)) if all(e <= tol for e in errs[i:])), None)


def crossovers(parents: list[np.ndarray]) -> np.ndarray:
    """Every child of two parents that takes one run of genes [i, j) from the second."""
    kids = []
    for a, b in itertools.permutations(range(len(parents)), 2):
        for i in range(parents[a].shape[0]):
            for j in range(i + 1, parents[a].shape[0] + 1):
                k = parents[a].copy()
                k[i:j] = parents[b][i:j]
                kids.append(k)
    return np.unique(np.array(kids), axis=0)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", required=True)
    ap.add_argument("--log", required=True, type=Path)
    ap.add_argument("--method", default="partial")
    ap.add_argument("--generations", type=int, default=1000,
                    help="Runs whose log reaches this generation are read.")
    ap.add_argument("--below", type=int, default=10**6,
                    help="Crossover parents: final turn cycles below this fitness.")
    ap.add_argument("--budgets", default="2400000,24000000")
    ap.add_argument("--kick-genes", default="2")
    ap.add_argument("--optimize-seeds", type=int, default=6)
    ap.add_argument("--climb", type=int, default=40)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("out/exact-model-search.json"))
    args = ap.parse_args(argv)
    robots = actual_robots()
    if args.robot not in robots:
        ap.error(f"unknown robot {args.robot!r}; use one of {', '.join(robots)}")
    if not args.log.is_file():
        ap.error(f"--log {args.log}: no such file")
    try:
        budgets = [int(b) for b in args.budgets.split(",")]
        kicks = [int(k) for k in args.kick_genes.split(",")]
    except ValueError:
        ap.error("--budgets and --kick-genes take comma-separated whole numbers")
    table = robots[args.robot]
    try:
        runs = read_complete_runs(args.log, args.generations)
    except InputError as e:
        ap.error(str(e))
    runs = {s: recs for (s, m), recs in runs.items() if m == args.method}
    if not runs:
        ap.error(f"--log {args.log}: no run of method {args.method!r} reaches generation "
                 f"{args.generations}")
    if any("model_error" not in r for recs in runs.values() for r in recs):
        ap.error(f"--log {args.log}: its records carry no per-row model error")
    seeds = {}
    for s, recs in sorted(runs.items()):
        recs.sort(key=lambda r: r["generation"])
        seeds[s] = {"exact_from": exact_from(recs), "final": recs[-1]["operational_fitness"],
                    "turn_cycle": recs[-1]["operational"]}
    parents = [parse_turn_cycle(v["turn_cycle"]) for v in seeds.values()
               if v["final"] < args.below]
    if len(parents) < 2:
        ap.error(f"crossover needs two runs below --below {args.below}; the log has "
                 f"{len(parents)}")
    lib = args.out.with_suffix(".shapes.json")
    lib.parent.mkdir(parents=True, exist_ok=True)
    shapes.load("builtin").without(args.robot).save(lib)
    found = {}
    for budget in budgets:
        for k in kicks:
            cfgs = [OptimizeConfig(evaluations=budget, chains=8, seed=s, shapes=str(lib),
                                   kick_genes=k) for s in range(args.optimize_seeds)]
            found[f"{budget} evaluations, kicks of {k} genes"] = [
                optimize(table.rows, cfg, table.effects, args.jobs)["fitness"] for cfg in cfgs]
    kids = crossovers(parents)
    objective = Objective(table.rows, 200, table.effects)
    scores = objective(kids)  # scored once: ranked by fitness, and each climb starts from it
    fit = fitness_of_search_score(scores, 200)
    climbed = []
    for n in np.argsort(-fit, kind="stable")[:args.climb]:
        _, score = climb(kids[n], int(scores[n]), objective)
        climbed.append(int(objective.fitness(score)))
    out = {"robot": args.robot, "seeds": seeds, "optimize_fitness": found,
           "crossover": {"parents": len(parents), "children": len(kids),
                         "best_child": int(fit.max()), "climbed": sorted(climbed)}}
    args.out.write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    print(json.dumps(main(), indent=1))
