"""The built-in emulator's tracker and the observer: every gait cycle of a run is seen, even
when the tracker gets round to the observer's connection late (a busy machine)."""

from __future__ import annotations

import itertools
import socket
import time

import numpy as np
import pytest

from pac_host.coverage import START_POSE, parse_turn_cycle
from pac_host.model import rollout, shifted_table
from pac_host.robot.connect import EmulatorOptions, connect
from pac_host.robot.linked import AppendLog, LinkedRobot
from pac_host.robot.observers import ObserverError, open_observer

BUDGET = 30


def test_a_tracker_slow_to_take_the_observer_loses_no_gait_cycle(monkeypatch):
    # connect() opens the placer's connection, then the observer's; the tracker takes the
    # second a second late, long after it answered the placer: a run started before then
    # walked gait cycles the observer was never sent
    real_accept = socket.socket.accept
    order = itertools.count()

    def slow_second(self):
        conn = real_accept(self)
        if next(order) == 1:
            time.sleep(1.0)
        return conn

    monkeypatch.setattr(socket.socket, "accept", slow_second)
    genes = parse_turn_cycle("12:20,3:9")
    with connect(None, None, EmulatorOptions(table=shifted_table(), noise=(0.0, 0.0))) as conn:
        linked = LinkedRobot(conn.robot, conn.observer, conn.placer, BUDGET, AppendLog(None))
        [result] = linked.run_tests(genes[None])
    [run] = linked.runs
    assert run["cycles_since_power_on"] == 0 and len(run["poses"]) == BUDGET
    truth = rollout(shifted_table().rows, START_POSE, run["gait_cycles"])[1:]
    assert np.allclose(run["poses"], truth, atol=1e-2)  # each pose the one after its cycle
    assert len(result.poses) == BUDGET + 1  # the start, then a pose per gait cycle


def test_a_tracker_that_never_greets_is_one_clear_error():
    server = socket.create_server(("127.0.0.1", 0))
    host, port = server.getsockname()[:2]
    observer = open_observer(f"tracker:{host}:{port}")
    conn, _ = server.accept()
    try:
        conn.sendall(b"POSE 1 3 1 10.0 20.0 90.0\n")  # poses, but no '#' line first
        with pytest.raises(ObserverError, match="no greeting from the tracker within 0.3 s"):
            observer.await_greeting(0.3)
    finally:
        observer.close()
        conn.close()
        server.close()
