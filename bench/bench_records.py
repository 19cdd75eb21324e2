"""Do the recorded PAL runs (bench/records, the docs' 30-seed figures) come out again here?

A run depends on its seed alone, so one recorded seed of each robot, run again on this machine
with this checkout, must give the same punctuation records, line for line (model rows,
tests, predictions, what the robot walked). A difference says the figures no longer describe
this code, or that this machine's arithmetic differs from the recording one's; the first
punctuation that differs is reported. The seed is run through bench_learning's own resume:
the record less that seed is the log, so only it runs.

Before that, the checks of the records and of the tools behind the docs' figures
(bench/test_records.py, bench/test_tools.py: the records give the docs' tables, their runs score
as walked, the issue's targets hold on them) run under pytest: records of past runs are no part
of ``make test``.

Targets: every check passes, every record reproduced. Usage: ``python bench/run.py --only
records`` (one PAL run a robot, two at a time: about ten minutes on two cores; ``--quick`` the
first record only).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import bench_learning
import learning_records

SEED = 0  # the seed run again
HERE = Path(__file__).resolve().parent
CHECKS = ("test_records.py", "test_tools.py", "test_demo.py")


def check() -> dict:
    """Run the records' and the tools' checks (pytest, in a process of its own)."""
    res = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:xdist", "-q",
                          "-p", "no:cacheprovider", *(str(HERE / c) for c in CHECKS)],
                         cwd=HERE.parent, capture_output=True, text=True)
    lines = res.stdout.strip().splitlines()
    return {"passed": res.returncode == 0, "summary": lines[-1] if lines else res.stderr[-500:]}


def verify(key: str, seed: int = SEED) -> dict:
    """Run ``seed`` of record ``key`` again (each recombination the record has); where its
    punctuations first differ, if they do."""
    entry = learning_records.index()[key]
    recombinations = tuple(entry.get("recombinations", ["partial"]))
    recs = learning_records.read_log(learning_records.RECORDS / entry["log"])
    runs = {m: learning_records.complete_runs(recs, m) for m in recombinations}
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp) / entry["robot"] / entry["method"]
        d.mkdir(parents=True)
        (d / "log.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs
                                             if r["seed"] != seed))
        bench_learning.measure([entry["robot"]], [entry["method"]], len(runs[recombinations[0]]),
                               Path(tmp), optimum_runs=1, optimum_evaluations=1_000_000,
                               recombination=recombinations)
        redone = learning_records.read_log(d / "log.jsonl")
    out: dict = {"seed": seed, "commit": entry["commit"], "reproduced": True}
    for m in recombinations:
        was, again = runs[m][seed], learning_records.complete_runs(redone, m).get(seed, [])
        first = next((k for k, (a, b) in enumerate(zip(was, again, strict=False)) if a != b),
                     None)
        if first is not None or len(again) != len(was):
            out["reproduced"] = False
            out.setdefault("first_different_punctuation", {})[m] = (
                first if first is not None else min(len(was), len(again)))
    return out


def run(quick: bool = False) -> dict:
    checks = check()
    keys = sorted(learning_records.index())
    if quick:
        keys = keys[:1]
    with ProcessPoolExecutor(2) as pool:
        out = dict(zip(keys, pool.map(verify, keys), strict=True))
    ok = all(r["reproduced"] for r in out.values())
    return {"checks": checks, "records": out, "targets": {
        "every_check_passes": {"value": checks["summary"], "target": "no failure",
                               "met": checks["passed"]},
        "every_record_reproduced": {
            "value": sum(r["reproduced"] for r in out.values()), "target": f"{len(out)}",
            "met": ok and bool(out)}}}


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
