"""The recorded PAL runs behind docs/results.md's 30-seed figures, and the figures from them.

A 30-seed run of one robot takes one to two hours on two cores, so the punctuation logs of the
runs the docs quote are kept in the repository (``bench/records/learning/ROBOT-METHOD.jsonl.gz``,
the complete runs of ``bench/bench_learning.py``'s ``log.jsonl``), with an index
(``bench/records/learning.json``) of the commit and command that made each and the figures
computed from it. The figures can then be checked without running PAL again
(bench/test_records.py recomputes them and walks every run's final turn cycle on
the robot), and a measurement stopped part way resumes in a fresh clone: ``bench_learning.py
--records bench/records`` starts each robot from its record, running only the seeds it lacks.

Usage:
``python bench/learning_records.py`` prints every record's figures, ``... table`` the docs'
markdown table of them;
``python bench/learning_records.py save ROBOT LOG --command "..."`` records the complete runs
of LOG (a bench_learning ``log.jsonl`` of ``--method``, the default's unless given) for ROBOT
at this checkout's commit; ``--recombinations full,partial`` records both recombinations of a
method with the model GA (``fit_ga``), and the index then carries each one's figures and the
paired tests of partial against full (the paper's question), which ``... comparison`` prints
as the docs' table.
"""

from __future__ import annotations

import argparse
import gzip
import json
import subprocess
import sys
from pathlib import Path

import known_best
import numpy as np

from pac_host.experiments.experiment import (
    TARGET,
    partial_against_full,
    punctuations_to,
    robot_time_report,
)

HERE = Path(__file__).resolve().parent
RECORDS = HERE / "records"
INDEX = RECORDS / "learning.json"
GENERATIONS = 1000  # a complete run: 25 punctuations after the first


def record_path(robot: str, method: str = "default", root: Path = RECORDS) -> Path:
    """Where the runs of bench_learning's ``method`` on ``robot`` are recorded."""
    return root / "learning" / f"{robot}-{method}.jsonl.gz"


def read_log(path: Path) -> list[dict]:
    """Punctuation records of a log, plain or gzipped."""
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as fh:
        return [json.loads(line) for line in fh if line.strip()]


def complete_runs(recs: list[dict], method: str = "partial",
                  generations: int | None = None) -> dict[int, list[dict]]:
    """Each seed's punctuation records, in order, for the runs that reached ``generations``
    (:data:`GENERATIONS` if None)."""
    generations = GENERATIONS if generations is None else generations
    by: dict[int, list[dict]] = {}
    for r in recs:
        if r["method"] == method:
            by.setdefault(int(r["seed"]), []).append(r)
    return {s: sorted(rs, key=lambda r: r["generation"]) for s, rs in sorted(by.items())
            if any(r["generation"] >= generations for r in rs)}


def figures(runs: dict[int, list[dict]], best_known: int) -> dict:
    """What docs/results.md quotes of a robot's runs: the issue's targets (90% of the best
    known reached, by how many punctuations; 95% at the end), through the experiment's own
    :func:`~pac_host.experiments.experiment.robot_time_report`, and by seed the finals, the
    punctuations
    to 90% and the later punctuations whose three tests the model predicted exactly."""
    rows = []
    for seed, rs in runs.items():
        coverage = [r["operational_fitness"] for r in rs]
        rows.append({"seed": seed, "method": "partial", "coverage": coverage,
                     "robot_hours": np.round(np.cumsum([r.get("robot_seconds", 0.0)
                                                        for r in rs]) / 3600.0, 4).tolist(),
                     "punctuations_to_target": punctuations_to(coverage, TARGET * best_known)})
    report = robot_time_report(rows, best_known)["methods"].get("partial", {})
    exact = [sum(all(p["fitness"] == o["fitness"] for p, o in zip(r["predicted"], r["observed"],
                                                                   strict=True))
                 for r in rs[1:]) for rs in runs.values()]
    finals = [row["coverage"][-1] for row in rows]
    return {"seeds": len(rows), "best_known": best_known,
            "reached_90": report.get("reached_target", 0),
            "median_punctuations_to_90": report.get("median_punctuations_to_target"),
            "punctuations_to_90_range": report.get("punctuations_to_target_range"),
            "median_robot_hours_to_90": report.get("median_robot_hours_to_target"),
            "ended_at_95": report.get("ended_at_final_target", 0),
            "final_mean": round(float(np.mean(finals)), 2) if finals else None,
            "finals": finals,
            "punctuations_to_90": [row["punctuations_to_target"] for row in rows],
            "median_exact_predictions": float(np.median(exact)) if exact else None,
            "later_punctuations": len(next(iter(runs.values()))) - 1 if runs else 0}


def index(root: Path = RECORDS) -> dict:
    """The records' index: by ``ROBOT-METHOD``, the commit, command, log and figures."""
    path = root / INDEX.name
    return json.loads(path.read_text()) if path.exists() else {}


def recombination_figures(runs: dict[int, list[dict]], best_known: int) -> dict:
    """:func:`figures`, and what the paper's question also asks of a recombination: the final
    model's error (mean |model - robot| over the 32 gait cycles and the seeds, forward, lateral,
    heading) and how many gait cycles the tests had walked by the end (range over seeds)."""
    err = np.array([[[e["F"], e["T"], e["dH"]] for e in rs[-1]["model_error"]]
                    for rs in runs.values()])
    walked = [len({g for r in rs for g in r["used_gait_ids"]}) for rs in runs.values()]
    return {**figures(runs, best_known),
            "final_model_error_FTdH": err.mean(axis=(0, 1)).round(3).tolist(),
            "rows_walked_range": [min(walked), max(walked)]}


def save(robot: str, log: Path, command: str, best_known: int, method: str = "default",
         root: Path = RECORDS, commit: str | None = None,
         recombinations: tuple[str, ...] = ("partial",)) -> dict:
    """Record the complete runs of ``log`` (bench_learning's ``method`` on ``robot``, each of
    ``recombinations``); the index, under ``ROBOT-METHOD``, gets the commit that made them (this
    checkout's if None), the command and the figures (partial recombination's, or the first
    one's), against ``best_known`` raised to the best any of the runs walked (as the
    experiment raises it). With more than one recombination the entry also has each one's
    :func:`recombination_figures` and, given full and partial, the paired tests of
    :func:`~pac_host.experiments.experiment.partial_against_full`."""
    recs = read_log(log)
    by = {m: complete_runs(recs, m) for m in recombinations}
    for m, runs in by.items():
        if not runs:
            raise ValueError(f"{log}: no complete run ({GENERATIONS} generations) of {m} "
                             "recombination to record")
    best_known = max([best_known] + [r["operational_fitness"] for runs in by.values()
                                     for rs in runs.values() for r in rs])
    keep = {(r["seed"], r["method"]) for runs in by.values() for rs in runs.values()
            for r in rs[:1]}
    path = record_path(robot, method, root)
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [json.dumps(r) + "\n" for r in recs if (r["seed"], r["method"]) in keep]
    with open(path, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", compresslevel=9,
                                                mtime=0) as fh:  # the same bytes each time
        fh.write("".join(lines).encode())
    if commit is None:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=HERE, check=False).stdout.strip()
    doc = index(root)
    key = f"{robot}-{method}"
    primary = "partial" if "partial" in by else recombinations[0]
    doc[key] = {"robot": robot, "method": method, "commit": commit, "command": command,
                "log": str(path.relative_to(root)), "recombinations": list(recombinations),
                "figures": figures(by[primary], best_known)}
    if len(by) > 1:
        doc[key]["by_recombination"] = {m: recombination_figures(runs, best_known)
                                        for m, runs in by.items()}
    if {"full", "partial"} <= set(by):
        doc[key]["partial_vs_full"] = partial_against_full(*(coverage_by_seed(by[m])
                                                             for m in ("partial", "full")))
    (root / INDEX.name).write_text(json.dumps(dict(sorted(doc.items())), indent=1) + "\n")
    return doc[key]


def coverage_by_seed(runs: dict[int, list[dict]]) -> dict[int, list[int]]:
    """By seed, the operational coverage after each punctuation of ``runs``."""
    return {s: [r["operational_fitness"] for r in rs] for s, rs in runs.items()}


BEGIN, END = "<!-- learning_records table -->", "<!-- end of learning_records table -->"


def markdown(root: Path = RECORDS) -> str:
    """The records' figures as the table docs/results.md carries (between
    :data:`BEGIN` and :data:`END`; bench/test_records.py checks they match)."""
    head = ("| robot (best known) | seeds | 90% of the best known: seeds, median punctuations "
            "(robot hours; range) | 95% at the end | final mean (range) | later punctuations "
            "predicted exactly, median | commit |\n|---|---|---|---|---|---|---|\n")
    rows = []
    for rec in index(root).values():
        if rec["method"] != "default":
            continue
        f = rec["figures"]
        med = f["median_punctuations_to_90"]
        lo_hi = f["punctuations_to_90_range"] or ["-", "-"]
        hours = f["median_robot_hours_to_90"]
        rows.append(
            f"| {rec['robot']} ({f['best_known']}) | {f['seeds']} | {f['reached_90']}/"
            f"{f['seeds']}, {_num(med)} ({_num(hours, 2)}; {lo_hi[0]}-{lo_hi[1]}) | "
            f"{f['ended_at_95']}/{f['seeds']} | {f['final_mean']} ({min(f['finals'])}-"
            f"{max(f['finals'])}) | {_num(f['median_exact_predictions'])} of "
            f"{f['later_punctuations']} | `{rec['commit']}` |")
    return head + "\n".join(rows) + "\n"


CMP_BEGIN = "<!-- learning_records comparison -->"
CMP_END = "<!-- end of learning_records comparison -->"


def comparison_markdown(root: Path = RECORDS) -> str:
    """The paper's question on the records that ran both recombinations: each one's figures,
    the paired tests of partial against full by robot, and pooled over every robot's seeds
    (the table docs/results.md carries between :data:`CMP_BEGIN` and
    :data:`CMP_END`)."""
    head = ("| robot (best known), method, seeds | recombination | finals (mean) | 90% reached, "
            "median punctuations (robot hours) | 95% at the end | final model error (mean F, "
            "T, dH over 32 gait cycles) | gait cycles walked by the end | partial against "
            "full: final, mean coverage (paired Wilcoxon p); final higher, lower |\n"
            "|---|---|---|---|---|---|---|---|\n")
    rows: list[str] = []
    pooled: dict[str, dict] = {"partial": {}, "full": {}}  # by (robot, seed)
    for rec in index(root).values():
        if "partial_vs_full" not in rec:
            continue
        t = rec["partial_vs_full"]
        runs = {m: complete_runs(read_log(root / rec["log"]), m) for m in ("partial", "full")}
        for m, by_seed in pooled.items():
            by_seed.update({(rec["robot"], s): c for s, c in coverage_by_seed(runs[m]).items()})
        for m in ("full", "partial"):
            f = rec["by_recombination"][m]
            err = ", ".join(f"{e:g}" for e in f["final_model_error_FTdH"])
            lo, hi = f["rows_walked_range"]
            vs = (f"{_p(t['final_coverage_wilcoxon'])}, {_p(t['mean_coverage_wilcoxon'])}; "
                  f"higher on {t['final_partial_higher']}, lower on {t['final_partial_lower']} "
                  f"of {t['seeds']}" if m == "partial" else "")
            rows.append(
                f"| {rec['robot']} ({f['best_known']}), {rec['method']}, {f['seeds']} | {m} | "
                f"{', '.join(map(str, f['finals']))} ({f['final_mean']}) | {f['reached_90']}/"
                f"{f['seeds']}, {_num(f['median_punctuations_to_90'])} "
                f"({_num(f['median_robot_hours_to_90'], 2)}) | {f['ended_at_95']}/{f['seeds']} | "
                f"{err} | {lo if lo == hi else f'{lo}-{hi}'} | {vs} |")
    if not rows:
        return head
    t = partial_against_full(pooled["partial"], pooled["full"])
    return (head + "\n".join(rows) + f"\n\nPooled over the {t['seeds']} seed pairs: final "
            f"coverage {_p(t['final_coverage_wilcoxon'])}, mean coverage "
            f"{_p(t['mean_coverage_wilcoxon'])}; partial higher on {t['final_partial_higher']}, "
            f"lower on {t['final_partial_lower']}.\n")


# what the docs carry between each pair of markers, by the command that prints it
TABLES = {"table": (BEGIN, END, markdown),
          "comparison": (CMP_BEGIN, CMP_END, comparison_markdown)}


def _p(test: dict) -> str:
    return f"p = {test['p_value']:.2g}"


def _num(v: float | None, digits: int = 1) -> str:
    if v is None:
        return "-"
    return str(int(v)) if float(v).is_integer() else f"{v:.{digits}f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what")
    sv = sub.add_parser("save", help="record a bench_learning log's complete runs")
    sv.add_argument("robot")
    sv.add_argument("log", type=Path)
    sv.add_argument("--method", default="default", help="bench_learning's method of the log")
    sv.add_argument("--commit", default=None,
                    help="the commit the runs were made with (default: this checkout's)")
    sv.add_argument("--command", required=True, help="the command that made the log")
    sv.add_argument("--best-known", type=int, default=None,
                    help="default: host/pac_host/model/best_known.json's")
    sv.add_argument("--recombinations", default="partial",
                    help="the log's recombinations to record, comma-separated (full,partial "
                         "for a method with the model GA: the paper's question)")
    sub.add_parser("table", help="the figures as the docs' markdown table")
    sub.add_parser("comparison", help="partial against full as the docs' markdown table")
    a = ap.parse_args(argv)
    if a.what in TABLES:
        print(TABLES[a.what][2](), end="")
        return 0
    if a.what == "save":
        if not a.log.exists():
            ap.error(f"{a.log}: no such log")
        best = a.best_known or known_best.fitness(a.robot)
        if best is None:
            ap.error(f"no best known for {a.robot!r}: give --best-known")
        try:
            entry = save(a.robot, a.log, a.command, best, a.method, commit=a.commit,
                         recombinations=tuple(a.recombinations.split(",")))
        except ValueError as e:
            print(f"learning_records: {e}", file=sys.stderr)
            return 2
        print(json.dumps(entry["figures"], indent=1))
        return 0
    for key, rec in index().items():
        f = rec["figures"]
        print(f"{key} ({rec['commit']}): {f['seeds']} seeds, 90% of {f['best_known']} on "
              f"{f['reached_90']} by a median of {f['median_punctuations_to_90']} punctuations "
              f"({f['punctuations_to_90_range']}), 95% at the end on {f['ended_at_95']}, "
              f"final mean {f['final_mean']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
