"""How fast PAL learns the robot, in robot tests: each learning method on several robots.

For the paper's shifted robot and the robots of ``pac_host.model.robots`` (independent row errors,
left/right asymmetry, library effects on a changed table, an effect outside the library), runs
``pac-host experiment`` (methods partial, full and the oracle control) with each learning
method, and reports per robot and method: seeds reaching 90% of the best known, the median
punctuations to it, seeds ending at 95% or more, the final model error per row, against the
oracle (the same CGA on the robot's true table).

Targets (the issue's, for the default method, on every robot, 30 seeds): 90% of the best known
on at least 27 of 30 seeds with a median of at most 10 punctuations; 95% at the end on at least
27 of 30. The default alone, 30 seeds, took 72 minutes on noisy_rows with ``--jobs 2`` on a
2-core machine (its eight search chains a punctuation, which shorten stalled loops by
windows of four genes; ``--search-chains 1``, the one chain of before, 10-12
minutes); the full measurement, every method with
full, partial and the oracle, takes hours:
``python bench/run.py --only learning``; ``--quick`` runs 2 seeds on each robot.
Every method's final turn cycles are also walked from 200 start poses drawn as a hand placement
leaves them (``placed_mean``, ``placed_p10_mean``); method ``placed`` is the default searching
for such a robot (``--placement-error 0.5,1``, what ``pac-host evolve`` does by default).
Method ``walking`` is the default with 20 million search evaluations a punctuation, a part of
what the time a real robot walks its tests gives the search (``pac-host evolve --port``).
Methods ``pooled`` and ``walking_pooled`` are ``default`` and ``walking`` with each turn cycle
scored on the model and three draws from its posterior (``--search-models 4``), the model's
own best tested beside the pooled best. Method ``closest_kicks`` is the default with closing
kicks by closeness alone (``--kick-length-cost 0``, the default before it preferred shorter
loops; docs/explanation/learning.md). Method ``own_restarts`` is the default with each chain's find
on the
model before a source its restarts climb again (the default before ``library_restarts``;
docs/explanation/learning.md, "Restarts from the library"). Method ``cut_moves`` is the default
with each
chain cut where its budget runs out, mid-move (the default before ``finish_moves``;
docs/explanation/learning.md, "Moves finished across punctuations"). Method ``fixed_effects`` is the
default with the sequence and world effects' parameters as the structure selection estimated
them (the default before ``refine_effects``; docs/explanation/learning.md, "Effects refitted with
the
rows").
``--search-evaluations N`` gives every method N search evaluations a punctuation (what more
host time buys). ``--records bench/records`` starts each robot and method from the runs
recorded there (``learning_records.py``: the docs' 30-seed figures), running only the seeds
they lack. Custom: ``python bench/bench_learning.py --seeds 3 --robots shifted,noisy_rows
--methods paper,default``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from dataclasses import replace
from pathlib import Path

import known_best
import learning_records
import numpy as np

from pac_host.experiments.experiment import ExperimentConfig, run_experiment
from pac_host.learning import profiles, test_selection
from pac_host.learning.config import PAPER, PALConfig, recombination_inert
from pac_host.model import measured_table, robots, shifted_table
from pac_host.search import shapes

WALKING = 20_000_000  # search evaluations a punctuation for method "walking"
# the learning methods compared: the paper's, and the whole-table correction
METHODS = {
    "paper": PALConfig(**PAPER),  # the paper's six differences, partial recombination
    "steps": PALConfig(**{**PAPER, "model_fitness": "steps"}),
    # the default profile: the whole table fitted, tests that teach the rows, no model GA, and
    # the anytime search between punctuations
    "default": profiles.apply("default", PALConfig()),
    # the default with the tests it had before (no candidates swapped to an unpinned row)
    "informative": profiles.apply("default", PALConfig(tests="informative")),
    # the default without the library of good sweeps (each search starts from short CGA runs)
    "no_shapes": profiles.apply("default", PALConfig(shapes="none")),
    "fit_ga": profiles.apply("default", PALConfig(model_generations=40)),  # + the model GA
    "paper_tests": profiles.apply("default", PALConfig(tests="paper")),  # the paper's tests
    # the default searching for a robot placed by hand (evolve's default:
    # pac_host.coverage.placement)
    "placed": profiles.apply("default", PALConfig(placement="0.5,1")),
    # the default with the search a real robot's walking pays for, in part: 20 million
    # evaluations a punctuation (about a minute of one core; `evolve --port` searches while
    # the robot walks its tests, some 13 minutes a punctuation)
    "walking": replace(profiles.apply("default", PALConfig()), search_evaluations=WALKING),
    # the same two, each turn cycle scored on the model and three draws from its posterior
    "pooled": profiles.apply("default", PALConfig(search_models=4)),
    "walking_pooled": replace(profiles.apply("default", PALConfig(search_models=4)),
                              search_evaluations=WALKING),
    # the default without its Thompson-sampled test (each search's whole budget on the model)
    "no_explore": replace(profiles.apply("default", PALConfig()), explore=0.0),
    # the default with closing kicks by closeness alone (the default before it preferred
    # shorter loops, pac_host.search.kicks.SHORTER)
    "closest_kicks": replace(profiles.apply("default", PALConfig()), kick_length_cost=0.0),
    # the default without trying shorter loops of a stalled chain's sweep (the default before
    # it, pac_host.search.shorten)
    "no_shorten": replace(profiles.apply("default", PALConfig()), shorten_after=0),
    # the default shortening loops by two genes only (the default before windows of four,
    # pac_host.search.shorten.shorter_windows)
    "no_windows": replace(profiles.apply("default", PALConfig()), shorten_windows=False),
    # the default with each chain's find on the model before a source like the library's, so
    # restarts climb it again (the default before library restarts)
    "own_restarts": replace(profiles.apply("default", PALConfig()), library_restarts=False),
    # the default with each chain cut where its budget runs out, mid-move (the default before
    # finish_moves)
    "cut_moves": replace(profiles.apply("default", PALConfig()), finish_moves=False),
    # the default with the sequence and world effects' parameters as the selection estimated
    # them (the default before refine_effects)
    "fixed_effects": replace(profiles.apply("default", PALConfig()), refine_effects=False),
}
# host/pac_host/model/best_known.json (checked by the tests); the experiments raise these to
# anything
# their own optimize chains or runs find
BEST_KNOWN = known_best.fitnesses()


def actual_robots() -> dict:
    return {"shifted": shifted_table(), **{n: robots.build(n) for n in robots.ROBOTS}}


def measure(robot_names, methods, seeds: int, out_root: Path, generations: int = 1000,
            optimum_runs: int = 4, optimum_evaluations: int = 10_000_000, jobs: int = 1,
            recombination=("partial", "oracle"), search_evaluations: int | None = None,
            search_chains: int | None = None, tests: str | None = None,
            records: Path | None = None) -> dict:
    """Each method on each robot; the best known on a robot comes from ``optimum_runs``
    chains of ``pac-host optimize`` (whatever the method, so all are measured against the
    same, strongest, search). ``search_evaluations`` replaces every method's search budget a
    punctuation and ``search_chains`` every anytime method's chains (what more host time
    buys); ``tests`` every method's choice of tests but the paper's. ``records``: a folder of
    recorded runs (``learning_records.py``); a robot and method without a log yet starts from
    its record there, so only the seeds it lacks are run."""
    all_robots = actual_robots()
    out: dict = {}
    for rname in robot_names:
        for mname in methods:
            pcfg = METHODS[mname]
            if search_evaluations is not None:
                pcfg = replace(pcfg, search_evaluations=search_evaluations)
            if search_chains is not None and pcfg.search != "cga":
                pcfg = replace(pcfg, search_chains=search_chains)
            if tests is not None and mname != "paper":
                pcfg = replace(pcfg, tests=tests)
            d = out_root / rname / mname
            if pcfg.shapes != "none":  # measured as on a robot nobody has searched: the
                # library without the sweeps found on this one
                d.mkdir(parents=True, exist_ok=True)
                lib = d / "shapes.json"
                shapes.load(pcfg.shapes).without(rname).save(lib)
                pcfg = replace(pcfg, shapes=str(lib))
            log = d / "log.jsonl"
            recorded = (learning_records.record_path(rname, mname, records)
                        if records is not None else None)
            if recorded is not None and recorded.exists() and not log.exists():
                d.mkdir(parents=True, exist_ok=True)
                log.write_text("".join(json.dumps(r) + "\n"
                                       for r in learning_records.read_log(recorded)))
            cfg = ExperimentConfig(
                seeds=seeds, generations=generations,
                # full where a model GA runs: elsewhere it would be partial's run again
                methods=tuple(m for m in recombination
                              if not (m == "full" and recombination_inert(pcfg))),
                initial_generations=1000, optimum_runs=optimum_runs, optimum_search="optimize",
                optimum_evaluations=optimum_evaluations, best_known=BEST_KNOWN.get(rname),
                pal=pcfg)
            s = run_experiment(d, cfg, measured_table(), all_robots[rname], jobs,
                               resume=log.exists())
            rt = s["robot_time"]
            entry = {"best_known": rt["best_known"]}
            for m, fig in rt["methods"].items():
                runs = [r for r in s["runs"] if r["method"] == m]
                err = np.array([[[e["F"], e["T"], e["dH"]] for e in r["final_model_error"]]
                                for r in runs])
                placed = np.array([[r["placed"]["mean"], r["placed"]["p10"]] for r in runs])
                entry[m] = {**fig, "finals": [r["coverage"][-1] for r in runs],
                            # each final turn cycle walked from 200 drawn start poses
                            "placed_mean": float(placed[:, 0].mean().round(2)),
                            "placed_p10_mean": float(placed[:, 1].mean().round(2)),
                            "model_error_mean_FTdH": err.mean(axis=(0, 1)).round(3).tolist(),
                            "model_error_max_row": float(err.max(axis=2).mean(axis=0).max()
                                                         .round(3))}
            if "tests" in s["comparison"]:
                entry["partial_vs_full"] = s["comparison"]["tests"]
            out.setdefault(rname, {})[mname] = entry
    return out


def _targets(res: dict, seeds: int) -> dict:
    need = int(np.ceil(0.9 * seeds))
    t = {}
    for rname, by in res.items():
        fig = by.get("default", {}).get("partial")
        if fig is None:
            continue
        med = fig["median_punctuations_to_target"]
        t[f"{rname}_reach_90"] = {"value": fig["reached_target"], "target": f">= {need}",
                                  "met": fig["reached_target"] >= need}
        t[f"{rname}_median_punctuations"] = {"value": med, "target": "<= 10",
                                             "met": med is not None and med <= 10}
        t[f"{rname}_end_95"] = {"value": fig["ended_at_final_target"], "target": f">= {need}",
                                "met": fig["ended_at_final_target"] >= need}
    return t


def run(quick: bool) -> dict:
    seeds = 2 if quick else 30
    with tempfile.TemporaryDirectory() as tmp:
        res = measure(list(actual_robots()), ["paper", "default", "fit_ga"], seeds, Path(tmp),
                      optimum_runs=2 if quick else 4,
                      optimum_evaluations=200_000 if quick else 10_000_000,
                      recombination=("full", "partial", "oracle"), jobs=2)
    return {"seeds": seeds, "results": res, "targets": _targets(res, seeds)}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--robots", default=",".join(actual_robots()))
    ap.add_argument("--methods", default="paper,default")
    ap.add_argument("--recombination", default="partial,oracle")
    ap.add_argument("--optimum-runs", type=int, default=2)
    ap.add_argument("--optimum-evaluations", type=int, default=10_000_000)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--generations", type=int, default=1000,
                    help="CGA generations a run (a punctuation every 40)")
    ap.add_argument("--search-evaluations", type=int, default=None,
                    help="every method's search evaluations a punctuation (default: the method's)")
    ap.add_argument("--search-chains", type=int, default=None,
                    help="every anytime method's search chains a punctuation "
                         "(default: the method's)")
    ap.add_argument("--tests", default=None, choices=test_selection.CHOICES,
                    help="every method's tests but the paper's (default: the method's)")
    ap.add_argument("--records", type=Path, default=None,
                    help="start each robot and method from its recorded runs in this folder "
                         "(bench/records: docs/results.md's), running only the seeds missing")
    ap.add_argument("--out", default="out/bench-learning")
    a = ap.parse_args()
    res = measure(a.robots.split(","), a.methods.split(","), a.seeds, Path(a.out),
                  generations=a.generations, optimum_runs=a.optimum_runs,
                  optimum_evaluations=a.optimum_evaluations,
                  jobs=a.jobs, recombination=tuple(a.recombination.split(",")),
                  search_evaluations=a.search_evaluations, search_chains=a.search_chains,
                  tests=a.tests, records=a.records)
    print(json.dumps({"results": res, "targets": _targets(res, a.seeds)}, indent=1))
