"""Robot-link benchmark: the host's own time per PAL punctuation, as a fraction of the time the
robot needs for the punctuation's three test runs at real speed.

`pac-host evolve`'s loop runs with the project's default GA settings against the built-in
emulator at real-time factor 0 (real pty, tracker, 200-gait-cycle tests). Host time per
punctuation = the wall time from one punctuation's end to the next one's, minus the time spent
on the robot (placing, loading, walking, observing): the CGA's 40 generations, the model GA,
logging, the model and turn-cycle files, the two PNGs and the state file. Robot time at real
speed is modelled from the protocol's timing (PROTOCOL.md 4.1): per gait cycle 1.16 s of
walking, its CYCLE and READY reports on the wire and the 100 ms listening window; per test one
STATUS, one LOAD per gene (with its EEPROM writes) and the RUN. The physical limit is the robot
walking, so the target is that the host adds under 1 %.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from pac_host.coverage import parse_turn_cycle
from pac_host.model import shifted_table
from pac_host.robot.connect import EmulatorOptions, connect
from pac_host.robot.evolve import EvolveConfig, evolve
from pac_protocol.timing import T_CYCLE_S, T_EEPROM_WRITE_S, T_PROCESS_S, T_RUN_S, wire_time

REQUEST, ACK, STATUS_R, READY, CYCLE, DONE = 9, 6, 12, 7, 11, 9


def exchange_s(reply_bytes: int, eeprom_writes: int = 0) -> float:
    return wire_time(READY + REQUEST + reply_bytes) + T_PROCESS_S + eeprom_writes * T_EEPROM_WRITE_S


def robot_seconds(tests: list[str], budget: int) -> float:
    """Modelled time of the tests at real speed (operator placement not counted)."""
    total = 0.0
    for t in tests:
        genes = int((parse_turn_cycle(t)[:, 1] > 0).sum())
        total += exchange_s(STATUS_R) * 2  # power-on count before the run; idle check
        total += genes * exchange_s(ACK, 3) + exchange_s(ACK)  # LOADs (2-4 writes) and RUN
        total += budget * (T_CYCLE_S + wire_time(CYCLE + READY) + T_RUN_S) + wire_time(DONE)
    return total


def run(quick: bool) -> dict:
    cfg = EvolveConfig(seed=1, generations=80 if quick else 200)
    records: list[dict] = []
    stamps: list[float] = []

    def seen(rec: dict) -> None:
        stamps.append(time.perf_counter())
        records.append(rec)

    with tempfile.TemporaryDirectory() as tmp, connect(
        None, None, EmulatorOptions(shifted_table(), noise=(0.5, 1.0))
    ) as conn:
        evolve(Path(tmp) / "run", cfg, conn, on_punctuation=seen)
    per = []
    for k in range(1, len(records)):
        wall = stamps[k] - stamps[k - 1]
        host = wall - records[k]["timing"]["robot_s"]
        real = robot_seconds(records[k]["tests"], cfg.budget)
        per.append({"generation": records[k]["generation"], "host_s": round(host, 3),
                    # the host's seconds, named for what ran (robot.evolve.timing_names)
                    **{n: s for n, s in records[k]["timing"].items() if n != "robot_s"},
                    "emulated_robot_s_at_factor_0": records[k]["timing"]["robot_s"],
                    "robot_s_at_real_speed": round(real, 1),
                    "fraction": round(host / real, 5)})
    worst = max(p["fraction"] for p in per)
    return {
        "punctuations": per,
        "median_host_s": round(statistics.median(p["host_s"] for p in per), 3),
        "median_fraction": round(statistics.median(p["fraction"] for p in per), 5),
        "settings": {"cga_population": cfg.cga_population, "model_population":
                     cfg.model_population, "interval": cfg.interval,
                     "model_generations": cfg.model_generations, "budget": cfg.budget},
        "targets": {"host_fraction_of_robot_time": {
            "value": worst, "target": "< 0.01 (worst punctuation)", "met": worst < 0.01}},
    }


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick=True), indent=1))
