"""Placing the robot: through the emulator's tracker socket (PLACE, with per-run noise seeds),
or by an operator through a callback."""

from __future__ import annotations

import socket

import pytest

from pac_host.robot.observers import ObserverError
from pac_host.robot.placement import OperatorPlacer, TrackerPlacer
from pac_sim.runner import SimConfig, SimStamp


@pytest.fixture
def sim():
    s = SimStamp(SimConfig(factor=0.0, tracker=("127.0.0.1", 0), tracker_noise=(0.5, 1.0)))
    s.start()
    yield s
    s.close()


def test_place_moves_the_world_and_seeds_the_noise_per_run(sim):
    placer = TrackerPlacer(*sim.tracker.address)
    a = placer.place("r1", (10, 20, 30), 5)
    assert sim.world.pose.tolist() == [10, 20, 30]
    assert a != (10, 20, 30) and max(abs(u - v) for u, v in zip(a, (10, 20, 30), strict=True)) < 6
    b = placer.place("r2", (10, 20, 30), 6)
    assert placer.place("r1 again", (10, 20, 30), 5) == a and b != a  # same run, same noise
    placer.close()


def test_a_bad_place_line_is_refused(sim):
    with socket.create_connection(sim.tracker.address, timeout=3) as s:
        s.sendall(b"PLACE 1 2\n")
        buf = b""
        while b"ERROR" not in buf:
            chunk = s.recv(4096)
            assert chunk
            buf += chunk
    assert b"ERROR expected PLACE x y h [seed]" in buf


def test_placer_against_something_that_never_answers():
    srv = socket.create_server(("127.0.0.1", 0))
    placer = TrackerPlacer(*srv.getsockname()[:2], timeout=0.2)
    with pytest.raises(ObserverError, match="no answer to PLACE within 0.2 s"):
        placer.place("r", (1, 2, 3), 0)
    placer.close()
    srv.close()


def test_operator_placer_asks_and_waits():
    said = []
    assert OperatorPlacer(said.append).place("g0-t1", (45, 30, 90), 0) is None
    assert said == ["run g0-t1: place the robot at (45 cm, 30 cm, heading 90 deg), then press "
                    "Enter"]
