"""Protocol benchmark: command round trips at 9600 baud emulated in real time, against the
wire's theoretical minimum (bytes x 10 bits / 9600), and emulator gait cycles per second at
real-time factor 0. Everything runs through a real pseudo-terminal and pyserial."""

from __future__ import annotations

import statistics
import time

from pac_protocol.link import StampLink
from pac_protocol.messages import Hello, Load, Read, Run, Status, Step, Stop
from pac_protocol.port import open_port
from pac_protocol.timing import T_EEPROM_WRITE_S, T_PROCESS_S, wire_time
from pac_sim.runner import SimConfig, SimStamp

# (name, request, reply LEN, EEPROM byte writes the Stamp makes before answering)
COMMANDS = [
    ("HELLO", Hello(), 3, 0),
    ("STATUS", Status(), 6, 0),
    ("READ", Read(0), 4, 0),
    ("LOAD (1-gene turn cycle)", Load(1, 0, 12, 3), 0, 4),
    ("STOP (idle)", Stop(), 0, 0),
    ("STEP (ack)", Step(12, 1), 0, 0),
    ("RUN (ack)", Run(1), 0, 0),
]
SLACK_S = 0.005  # allowed above the modelled minimum: OS scheduling and pty latency


def round_trips(reps: int) -> dict:
    out = {}
    with SimStamp(SimConfig(factor=1.0)) as sim:
        port = open_port(sim.path)
        try:
            link = StampLink(port, name=sim.path)
            link.hello()
            link.load([(12, 1)])
            for name, msg, reply_len, writes in COMMANDS:
                times = []
                for _ in range(reps):
                    link.request(msg)
                    times.append(link.last_round_trip_s)
                    if isinstance(msg, Step | Run):
                        link.wait_done()  # one real gait cycle, 1.16 s
                nbytes = 9 + 6 + reply_len
                wire = wire_time(nbytes)
                modelled = wire + T_PROCESS_S + writes * T_EEPROM_WRITE_S
                med = statistics.median(times)
                out[name] = {
                    "bytes_on_wire": nbytes,
                    "theoretical_min_ms": round(wire * 1e3, 2),
                    "modelled_min_ms": round(modelled * 1e3, 2),
                    "median_ms": round(med * 1e3, 2),
                    "max_ms": round(max(times) * 1e3, 2),
                    "ratio_to_theoretical": round(med / wire, 2),
                    "met": med <= modelled + SLACK_S,
                }
            assert link.stats.retries == 0, link.stats
        finally:
            port.close()
    return out


def cycles_per_second(n: int, window_floor_s: float | None) -> float:
    cfg = SimConfig(factor=0.0) if window_floor_s is None else SimConfig(
        factor=0.0, window_floor_s=window_floor_s
    )
    with SimStamp(cfg) as sim:
        port = open_port(sim.path)
        try:
            link = StampLink(port)
            link.hello()
            link.load([(12, 5), (3, 2), (25, 4)])
            t0 = time.perf_counter()
            link.run(n)
            cycles, done = link.wait_done()
            dt = time.perf_counter() - t0
            assert done.done == n == len(cycles), (done, len(cycles))
        finally:
            port.close()
    return n / dt


def run(quick: bool) -> dict:
    reps = 3 if quick else 10
    rt = round_trips(reps)
    n = 300 if quick else 3000
    cps = cycles_per_second(n, None)
    cps_no_window = cycles_per_second(n, 0.0)
    targets = {
        f"round trip {name} within {SLACK_S * 1e3:g} ms of modelled minimum": {
            "value": v["median_ms"],
            "target": f"<= {v['modelled_min_ms'] + SLACK_S * 1e3:.2f} ms",
            "met": v["met"],
        }
        for name, v in rt.items()
    }
    targets["gait cycles per second at realtime 0"] = {
        "value": round(cps, 1),
        "target": ">= 200 (2 ms listening window per gait cycle)",
        "met": cps >= 200,
    }
    return {
        "round_trips_9600_baud_realtime_1": rt,
        "repetitions_per_command": reps,
        "gait_cycles": n,
        "gait_cycles_per_s_realtime_0": round(cps, 1),
        "gait_cycles_per_s_realtime_0_no_window_floor": round(cps_no_window, 1),
        "targets": targets,
    }
