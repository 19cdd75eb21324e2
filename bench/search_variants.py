"""The search alone, on each robot's exact table: settings of ``pac-host optimize`` compared seed
for seed, where the model cannot be the reason a run ends short.

For each robot of ``--robots`` (the learning bench's: the shifted robot and those of
``pac_host.model.robots``), from the library less the sweeps found on that robot (as the bench gives
it), runs ``optimize`` with ``--chains`` chains and ``--evaluations`` evaluations for each
closing-kick length cost of ``--kick-length-costs`` (cm a gait cycle of the kicked loop weighs
in the repair; :mod:`pac_host.search.kicks`) and each of ``--shorten-after`` (kicks without
progress after which a chain tries shorter loops of its sweep, 0: never;
:mod:`pac_host.search.shorten`) and each of ``--windows`` (1: those shorter loops include
re-set windows of four genes, 0: two genes only), seeds ``--seeds`` (FIRST-LAST). Reports per
robot and variant the final fitness of each seed, their mean and, against the first variant, on
how many seeds it ended higher and lower, with the paired Wilcoxon test; and over every robot
pooled.

Example (docs/explanation/learning.md, "Kicks that prefer shorter loops"; one chain as a PAL run's
chains
are, about 20 s a run on one core):
``python bench/search_variants.py --robots noisy_rows,asymmetric,outside_library --chains 1
--evaluations 3000000 --seeds 100-115 --kick-length-costs 0,1``

Example (docs/explanation/learning.md, "Shorter loops of a stalled sweep"; eight chains and a
punctuation's
evaluations, as the default profile searches each corrected model):
``python bench/search_variants.py --robots
shifted,noisy_rows,asymmetric,library_on_changed,outside_library --chains 8 --evaluations 3200000
--seeds 0-9 --kick-length-costs 1 --shorten-after 0,5``

Example (docs/explanation/learning.md, "Shorter windows"): the same with ``--shorten-after 5
--windows 0,1``.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from pac_host.errors import InputError
from pac_host.experiments.stats import wilcoxon_signed_rank
from pac_host.search import shapes
from pac_host.search.kicks import check_length_cost
from pac_host.search.optimize import OptimizeConfig, optimize
from pac_host.search.shorten import check_shorten_after

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_learning import actual_robots  # noqa: E402


def one_run(robot: str, library: str, chains: int, evaluations: int, seed: int,
            cost: float, shorten_after: int = 0, windows: bool = True) -> int:
    """The fitness ``optimize`` ends at on ``robot``'s exact table."""
    table = actual_robots()[robot]
    cfg = OptimizeConfig(evaluations=evaluations, chains=chains, seed=seed, shapes=library,
                         kick_length_cost=cost, shorten_after=shorten_after,
                         shorten_windows=windows)
    return int(optimize(table.rows, cfg, table.effects)["fitness"])


def label(cost: float, shorten_after: int, windows: bool = True) -> str:
    """A variant's name in the report."""
    return f"cost {cost:g}, shorten after {shorten_after}" + ("" if windows else ", pairs only")


def compare(finals: dict[str, list[int]]) -> dict:
    """Per variant: the finals, their mean and, against the first variant's, the seeds higher
    and lower and the paired Wilcoxon p."""
    base_name, base = next(iter(finals.items()))
    out = {}
    for name, f in finals.items():
        row = {"finals": f, "mean": round(sum(f) / len(f), 3)}
        if name != base_name:
            row.update(higher=sum(a > b for a, b in zip(f, base, strict=True)),
                       lower=sum(a < b for a, b in zip(f, base, strict=True)),
                       p_value=round(wilcoxon_signed_rank(f, base)["p_value"], 4))
        out[name] = row
    return out


def _seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    lo, hi = int(first), int(last or first)
    if not 0 <= lo <= hi:
        raise ValueError(text)
    return list(range(lo, hi + 1))


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="noisy_rows")
    ap.add_argument("--chains", type=int, default=1)
    ap.add_argument("--evaluations", type=int, default=3_000_000)
    ap.add_argument("--seeds", default="100-115", help="FIRST-LAST (or one seed)")
    ap.add_argument("--kick-length-costs", default="0,1")
    ap.add_argument("--shorten-after", default="0", help="comma-separated kicks (0: never)")
    ap.add_argument("--windows", default="1", help="comma-separated 0/1: two genes only / "
                    "also windows of four")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("out/search-variants.json"))
    args = ap.parse_args(argv)
    names = [r.strip() for r in args.robots.split(",") if r.strip()]
    known = actual_robots()
    bad = [r for r in names if r not in known]
    if not names or bad:
        ap.error(f"unknown robot {bad[0] if bad else '(none)'!r}; use {', '.join(known)}")
    try:
        seeds = _seeds(args.seeds)
        costs = [float(c) for c in args.kick_length_costs.split(",")]
        afters = [int(k) for k in args.shorten_after.split(",")]
        windows = [{"0": False, "1": True}[w.strip()] for w in args.windows.split(",")]
    except (ValueError, KeyError):
        ap.error("--seeds takes FIRST-LAST, --kick-length-costs comma-separated numbers and "
                 "--shorten-after comma-separated whole numbers, --windows 0 and/or 1")
    try:
        for c in costs:
            check_length_cost(c)
        for k in afters:
            check_shorten_after(k)
    except InputError as e:
        ap.error(str(e))
    if any(len(set(v)) < len(v) for v in (costs, afters, windows)):
        ap.error("--kick-length-costs, --shorten-after and --windows must be distinct")
    variants = [(c, k, w) for c in costs for k in afters for w in windows]
    if args.chains < 1 or args.evaluations < args.chains or args.jobs < 1:
        ap.error("--chains and --jobs must be 1 or more, --evaluations at least --chains")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    jobs = []
    for robot in names:
        lib = args.out.parent / f"{args.out.stem}.{robot}.shapes.json"
        shapes.load("builtin").without(robot).save(lib)
        jobs += [(robot, str(lib), args.chains, args.evaluations, s, c, k, w)
                 for c, k, w in variants for s in seeds]
    with ProcessPoolExecutor(max_workers=args.jobs) as ex:
        done = list(ex.map(one_run, *zip(*jobs, strict=True)))
    finals: dict[str, dict[str, list[int]]] = {}
    for (robot, _, _, _, _, cost, after, w), f in zip(jobs, done, strict=True):
        finals.setdefault(robot, {}).setdefault(label(cost, after, w), []).append(f)
    pooled: dict[str, list[int]] = {label(c, k, w): [] for c, k, w in variants}
    for by_variant in finals.values():
        for v, f in by_variant.items():
            pooled[v] += f
    out = {"settings": {"chains": args.chains, "evaluations": args.evaluations,
                        "seeds": [seeds[0], seeds[-1]], "kick_length_costs": costs,
                        "shorten_after": afters, "windows": windows},
           "robots": {r: compare(by_variant) for r, by_variant in finals.items()},
           "pooled": compare(pooled)}
    args.out.write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    print(json.dumps(main(), indent=1))
