"""Does `make demo`'s evolve run end near the best known, with its model's predictions converging?

The command is the Makefile's own (the ``pac-host evolve`` line of its ``demo`` recipe, run here
into a temporary directory), so this measures what a newcomer's ``make demo`` does: PAL over
a pseudo-terminal against the emulated shifted robot. Figures: the operational turn cycle's
coverage on the robot at each punctuation, the predicted against the observed fitness of each
test, and the best known on the shifted robot (host/pac_host/model/best_known.json).

Targets: the run ends within 10% of the best known; the predictions converge, the model
predicting every test of the last three punctuations within one block (the first punctuation,
before any correction, is far off). Usage: ``python bench/run.py --only demo`` (about a
minute on an idle core).
"""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

from pac_host.model.best_known import fitness as best_known_fitness

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
LAST = 3  # punctuations whose predictions must be within one block
CLOSE = 1


def demo_evolve_args(makefile: Path = ROOT / "Makefile") -> list[str]:
    """The arguments of the ``pac-host evolve`` line in the Makefile's ``demo`` recipe, less
    its ``--out``."""
    text = makefile.read_text()
    recipe = re.search(r"^demo:.*\n((?:\t.*\n)+)", text, re.MULTILINE)
    if recipe is None:
        raise ValueError("the Makefile has no demo recipe")
    line = next((x for x in recipe.group(1).splitlines() if "pac-host evolve" in x), None)
    if line is None:
        raise ValueError("the Makefile's demo recipe runs no pac-host evolve")
    args = shlex.split(line.split("pac-host evolve", 1)[1])
    if "--out" in args:
        i = args.index("--out")
        del args[i:i + 2]
    return args


def figures(out: Path, best_known: int) -> dict:
    """What the run's log says: coverage by punctuation and the prediction errors."""
    recs = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines() if x.strip()]
    errors = [[abs(p["fitness"] - o["fitness"]) for p, o in
               zip(r["predicted"], r["observed"], strict=True)] for r in recs]
    final = recs[-1]["operational_fitness"]
    return {"turn_cycle": recs[-1]["operational"], "final": final, "best_known": best_known,
            "fraction_of_best_known": round(final / best_known, 4),
            "operational_by_punctuation": [r["operational_fitness"] for r in recs],
            "prediction_errors": errors,
            "last_max_error": max(max(e) for e in errors[-LAST:])}


def run(quick: bool = False) -> dict:
    best = best_known_fitness("shifted")
    args = demo_evolve_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "demo-evolve"
        cmd = [str(Path(sys.executable).with_name("pac-host")), "evolve", "--out", str(out),
               *args]
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise RuntimeError(f"{shlex.join(cmd)} failed: {done.stderr.strip()[-400:]}")
        res = figures(out, best)
    res["command"] = "pac-host evolve --out OUT " + shlex.join(args)
    res["targets"] = {
        "within_10_percent_of_best_known": {
            "value": res["fraction_of_best_known"], "target": ">= 0.9",
            "met": res["fraction_of_best_known"] >= 0.9},
        "predictions_converge": {
            "value": res["last_max_error"], "target": f"<= {CLOSE} in the last {LAST}",
            "met": res["last_max_error"] <= CLOSE
            and max(res["prediction_errors"][0]) > CLOSE}}
    return res


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
