"""Soak benchmark: `pac-host evolve` on a line that drops and corrupts bytes.

Each run is 3 punctuations (40 CGA generations, one every 20; tests of 100 gait cycles; small
GA settings: the link, not the GA, is under test) against an emulator at real-time factor 0,
with its own fault seed. A run passes if it completes with exactly the decisions of the clean
run: every punctuation record (tests, observed figures, model fitness, operational solution),
the final model and the turn cycle. Three sets:

- ``model_1pct``: the protocol-level emulator, 1% of the bytes dropped and 1% corrupted, each
  way; target: every run passes.
- ``model_2pct``: the same at 2% and 2%; reported (each failure with its error line).
- ``firmware_1pct``: `pac-sim --firmware` (firmware/servobot.bs2 in the PBASIC interpreter,
  through the real-robot path: a port, the tracker as observer and placer) at 1% and 1%;
  target: every run passes.

Overhead: the wall time of a noisy run against the clean one. At factor 0 the walking costs
almost nothing and the recovery's timeouts (scaled by 0.25 for the built-in emulator) are most
of the time, so the ratio is not the overhead a robot would see; the real-speed estimate takes
the extra wall time, scales the timeouts back (x4, an upper bound: wire time does not scale),
and divides by the modelled real-speed time of the same tests (bench_link.robot_seconds).

Give-up: a robot muted after 3 gait cycles, at real speed with the default timeouts; the time
from its last report to the error, against the stated bound (recovery.give_up_s: EVENT_TIMEOUT
+ 3 READY_TIMEOUT).
"""

from __future__ import annotations

import contextlib
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_link import robot_seconds  # noqa: E402

from pac_host.coverage import parse_turn_cycle  # noqa: E402
from pac_host.errors import TOOLKIT_ERRORS  # noqa: E402
from pac_host.model import shifted_table  # noqa: E402
from pac_host.robot.api import StampRobot  # noqa: E402
from pac_host.robot.connect import EmulatorOptions, connect  # noqa: E402
from pac_host.robot.evolve import EvolveConfig, evolve  # noqa: E402
from pac_host.robot.linked import LinkedRobot  # noqa: E402
from pac_host.robot.observers import open_observer  # noqa: E402
from pac_host.robot.placement import TrackerPlacer  # noqa: E402
from pac_host.robot.recovery import give_up_s  # noqa: E402
from pac_protocol.link import StampLink  # noqa: E402
from pac_protocol.port import open_port  # noqa: E402
from pac_sim.line import Faults  # noqa: E402
from pac_sim.runner import SimConfig, SimStamp  # noqa: E402

FIRMWARE = HERE.parent / "firmware" / "servobot.bs2"
CFG = EvolveConfig(seed=4, generations=40, interval=20, budget=100, cga_population=24,
                   model_population=12, model_generations=15, initial_generations=30)
NOISE = (0.5, 1.0)
TIMEOUT_SCALE = 0.25  # the built-in emulator's timeouts at factor 0 (robot.connect)
COUNTS = ("retries", "resyncs", "redone_tests", "implausible_reports")


@contextlib.contextmanager
def _firmware_connection(p: float, seed: int):
    sim = SimStamp(SimConfig(factor=0.0, firmware=str(FIRMWARE), seed=seed,
                             faults=Faults(p, p), table=shifted_table(), tracker_noise=NOISE,
                             tracker=("127.0.0.1", 0)))
    sim.start()
    try:
        host, port = sim.tracker.address
        with connect(sim.path, f"tracker:{host}:{port}", None, placer="tracker") as conn:
            yield conn
    finally:
        sim.close()


def one_run(p: float, seed: int, firmware: bool) -> dict:
    """One evolve run; its decisions, recovery counts and wall time, or its error."""
    conn_cm = (_firmware_connection(p, seed) if firmware else
               connect(None, None, EmulatorOptions(shifted_table(), noise=NOISE, seed=seed,
                                                   drop_prob=p, corrupt_prob=p)))
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        try:
            with conn_cm as conn:
                evolve(Path(tmp) / "run", CFG, conn)
        except TOOLKIT_ERRORS as e:
            return {"seed": seed, "error": str(e), "wall_s": round(time.perf_counter() - t0, 2)}
        wall = time.perf_counter() - t0
        import json

        log = [json.loads(x) for x in (Path(tmp) / "run" / "log.jsonl").read_text().splitlines()]
    decisions = [{k: v for k, v in r.items()
                  if k not in ("timing", "recovery", "true_error_on_used")} for r in log]
    counts = {k: sum(r["recovery"][k] for r in log) for k in COUNTS}
    tests = [t for r in log for t in r["tests"]]
    return {"seed": seed, "wall_s": round(wall, 2), "recovery": counts,
            "decisions": decisions, "tests": tests}


def soak(p: float, seeds: list[int], firmware: bool, clean: dict) -> dict:
    runs = [one_run(p, s, firmware) for s in seeds]
    same = [r for r in runs if r.get("decisions") == clean["decisions"]]
    failed = [{"seed": r["seed"], "why": r.get("error", "completed with other decisions")}
              for r in runs if r not in same]
    extra = [r["wall_s"] - clean["wall_s"] for r in same]
    real = robot_seconds(clean["tests"], CFG.budget)
    out = {
        "fault_prob_each": p, "runs": len(runs), "identical_to_clean": len(same),
        "failed": failed,
        "recovery_totals": {k: sum(r["recovery"][k] for r in same) for k in COUNTS},
        "recovery_per_run_max": {k: max((r["recovery"][k] for r in same), default=0)
                                 for k in COUNTS},
        "clean_wall_s": clean["wall_s"],
        "median_wall_s": round(statistics.median(r["wall_s"] for r in runs), 2),
        "median_wall_ratio_at_factor_0": round(
            statistics.median(r["wall_s"] for r in runs) / clean["wall_s"], 2),
    }
    if extra:
        scale = 1 if firmware else 1 / TIMEOUT_SCALE  # the firmware path uses real timeouts
        est = float(np.median(extra)) * scale / real
        out["real_speed_overhead_estimate"] = round(est, 4)
        out["real_speed_robot_s_modelled"] = round(real, 1)
    return out


def give_up_time() -> dict:
    """A robot muted after 3 gait cycles at real speed: seconds from its last report to the
    error, with the default timeouts."""
    with SimStamp(SimConfig(factor=1.0, tracker=("127.0.0.1", 0), mute_after=3)) as sim:
        port = open_port(sim.path)
        host, tport = sim.tracker.address
        observer, placer = open_observer(f"tracker:{host}:{tport}"), TrackerPlacer(host, tport)
        robot = StampRobot(StampLink(port, name=sim.path))
        robot.hello()
        last = [time.monotonic()]
        linked = LinkedRobot(robot, observer, placer, 10, lambda d: None)
        inner = observer.on_cycle

        def seen(power_on: int) -> None:
            last.append(time.monotonic())
            inner(power_on)

        observer.on_cycle = seen
        error = ""
        try:
            linked.run_tests(parse_turn_cycle("12:10")[None])
        except TOOLKIT_ERRORS as e:
            error = str(e)
        took = time.monotonic() - last[-1]
        for c in (observer, placer, port):
            c.close()
    bound = give_up_s()
    return {"seconds_after_last_report": round(took, 2), "bound_s": bound, "error": error,
            "met": bool(error) and took <= bound + 1.0}


def run(quick: bool) -> dict:
    n = 4 if quick else 20
    seeds = list(range(1, n + 1))
    clean_model = one_run(0.0, 0, firmware=False)
    clean_fw = one_run(0.0, 0, firmware=True)
    res = {
        "settings": {"generations": CFG.generations, "interval": CFG.interval,
                     "budget": CFG.budget, "punctuations": 3, "fault_seeds": seeds},
        "clean_identical_model_vs_firmware": clean_model["decisions"] == clean_fw["decisions"],
        "model_1pct": soak(0.01, seeds, False, clean_model),
        "model_2pct": soak(0.02, seeds, False, clean_model),
        "firmware_1pct": soak(0.01, seeds[: max(2, n // 2)] if quick else seeds, True, clean_fw),
        "give_up": give_up_time(),
    }
    res["targets"] = {
        "model_1pct_all_identical": {
            "value": f"{res['model_1pct']['identical_to_clean']}/{n}", "target": f"{n}/{n}",
            "met": res["model_1pct"]["identical_to_clean"] == n},
        "firmware_1pct_all_identical": {
            "value": f"{res['firmware_1pct']['identical_to_clean']}/"
                     f"{res['firmware_1pct']['runs']}",
            "target": "all", "met": not res["firmware_1pct"]["failed"]},
        "model_2pct_reported": {
            "value": f"{res['model_2pct']['identical_to_clean']}/{n}",
            "target": "all, or each failure's reason", "met": True},
        "give_up_within_bound": {
            "value": res["give_up"]["seconds_after_last_report"],
            "target": f"<= {res['give_up']['bound_s']} s (+1 s margin)",
            "met": res["give_up"]["met"]},
    }
    return res


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick=True), indent=1))
