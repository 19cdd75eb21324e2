"""PAL on a noisy robot: the default `experiment` (partial recombination, the default profile)
on an actual robot with step noise, each punctuation's operational turn cycle measured by its
mean over 400 fresh noisy walks, against the best known robust sweep on that robot
(`pac_host/model/best_known.json`'s robust record at that noise, or the experiment's own
optimum where that is higher).

Targets (issue): the operational sweep's expected coverage reaches 90% of the best known by a
median of at most 5 punctuations, and ends at 95% or more on at least 9 of 10 seeds; on the
shifted robot and others, at 0.3 cm / 1 deg and 0.15 cm / 0.5 deg.

Usage: ``python bench/bench_noisy_pal.py [--robot shifted|FILE] [--step-noise 0.3,1]
[--seeds 10] [--generations 1000] [--profile paper]`` or ``python bench/run.py --only
noisy_pal`` (the shifted robot at 0.3 cm / 1 deg, 10 seeds of 25 punctuations, two runs at a
time: about 10 minutes on two cores; ``--quick``: 2 seeds of 5 punctuations). ``--profile
paper`` runs the paper's method (no library) on the same robot, to compare.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pac_host.search import shapes

PAC_HOST = Path(sys.executable).parent / "pac-host"
TARGET, FINAL_TARGET, SHARE, MEDIAN_PUNCTUATIONS = 0.90, 0.95, 0.9, 5


def run(quick: bool = False, robot: str = "shifted", step_noise: str = "0.3,1",
        seeds: int | None = None, generations: int | None = None,
        profile: str = "default") -> dict:
    seeds = seeds or (2 if quick else 10)
    generations = generations or (200 if quick else 1000)
    with tempfile.TemporaryDirectory() as tmp:
        out, library = Path(tmp) / "x", Path(tmp) / "library.json"
        # the project's library less the sweeps found on the robot: a robot nobody has searched
        shapes.load("builtin").without(robot).save(library)
        cmd = [str(PAC_HOST), "experiment", "--actual", robot, "--step-noise", step_noise,
               "--seeds", str(seeds), "--generations", str(generations), "--methods",
               "partial", "--jobs", "2", "--quiet", "--out", str(out)]
        # the paper's method as the paper ran it (no library), beside the default
        cmd[-2:-2] = ["--profile", "paper"] if profile == "paper" else ["--shapes", str(library)]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        summary = json.loads((out / "summary.json").read_text())
    best = summary["best_known"]
    rt = summary["robot_time"]["methods"]["partial"]
    runs = summary["runs"]
    finals = [r["coverage"][-1] for r in runs]
    reached = [r["punctuations_to_target"] for r in runs]
    ended = sum(f >= FINAL_TARGET * best["fitness"] for f in finals)
    return {
        "command": " ".join(["pac-host", *cmd[1:-1], "OUT"]), "seconds": round(wall, 1),
        "best_known": best, "figures": summary["figures"],
        "coverage": {r["seed"]: r["coverage"] for r in runs},
        "final_over_best_known": [round(f / best["fitness"], 3) for f in finals],
        "punctuations_to_90": reached, "robot_time": rt,
        "targets": {
            "median_punctuations_to_90": {
                "target": MEDIAN_PUNCTUATIONS, "value": rt.get("median_punctuations_to_target"),
                "met": rt.get("median_punctuations_to_target") is not None
                and rt["median_punctuations_to_target"] <= MEDIAN_PUNCTUATIONS},
            "ended_at_95": {"target": f">= {SHARE:.0%} of seeds", "value": f"{ended}/{seeds}",
                            "met": ended >= SHARE * seeds}},
    }


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--robot", default="shifted")
    ap.add_argument("--step-noise", default="0.3,1")
    ap.add_argument("--seeds", type=int, default=None)
    ap.add_argument("--generations", type=int, default=None)
    ap.add_argument("--profile", choices=("default", "paper"), default="default")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    print(json.dumps(run(a.quick, a.robot, a.step_noise, a.seeds, a.generations, a.profile),
                     indent=1))
