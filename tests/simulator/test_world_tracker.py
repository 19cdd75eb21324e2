"""The simulated world moves exactly as the model says; the tracker feed; EEPROM persistence."""

from __future__ import annotations

import socket
import threading

import numpy as np
import pytest

from pac_host.errors import InputError
from pac_host.model import parse_effect, rollout, shifted_table
from pac_protocol.link import StampLink
from pac_protocol.tracker_line import parse_pose_line as parse_pose
from pac_sim.eeprom import Eeprom
from pac_sim.runner import SimConfig, SimStamp

EFFECTS = tuple(
    parse_effect(e)
    for e in ("transition:alpha=0.3", "battery_sag:beta=0.002", "floor_slope:s=0.4,theta=30")
)


def test_world_follows_the_model_across_runs(make_sim):
    sim, port = make_sim(effects=EFFECTS, start=(50.0, 20.0, 80.0))
    link = StampLink(port)
    link.hello()
    link.load([(12, 2), (3, 1), (25, 2)])
    link.run(9)
    ids1 = [c.gait for c in link.wait_done()[0]]
    link.step(17, 4)
    ids2 = [c.gait for c in link.wait_done()[0]]
    rows = shifted_table().rows
    p1 = rollout(rows, (50.0, 20.0, 80.0), ids1, EFFECTS, n0=0)
    p2 = rollout(rows, p1[-1], ids2, EFFECTS, n0=len(ids1))
    true = np.array([h.true_pose for h in sim.world.history])
    np.testing.assert_allclose(true, np.vstack([p1[1:], p2[1:]]), atol=1e-9)
    assert [h.power_on for h in sim.world.history] == list(range(1, 14))


def _lines(sock: socket.socket, n: int) -> list[str]:
    buf = b""
    while buf.count(b"\n") < n:
        chunk = sock.recv(4096)
        assert chunk, "tracker closed"
        buf += chunk
    return buf.decode().splitlines()[:n]


def test_tracker_publishes_one_line_per_gait_cycle(make_sim):
    sim, port = make_sim(tracker=("127.0.0.1", 0), tracker_noise=(1.5, 2.0), seed=4)
    with socket.create_connection(sim.tracker.address, timeout=3) as s:
        head = _lines(s, 2)
        assert head[0].startswith("# pac-sim tracker 1")
        snap = parse_pose(head[1])
        assert (snap.seq, snap.gait, snap.power_on) == (0, -1, 0)
        assert np.allclose(snap.pose, (45, 30, 90), atol=10) and snap.pose != (45, 30, 90)
        link = StampLink(port)
        link.hello()
        link.step(9, 3)
        link.wait_done()
        got = [parse_pose(line) for line in _lines(s, 3)]
    assert [(g.seq, g.gait, g.power_on) for g in got] == [(1, 9, 1), (2, 9, 2), (3, 9, 3)]
    hist = sim.world.history
    np.testing.assert_allclose([g.pose for g in got], [h.observed for h in hist], atol=6e-4)
    err = np.array([h.observed for h in hist]) - np.array([h.true_pose for h in hist])
    assert np.all(np.abs(err) > 0)  # noise is applied


def test_a_gait_cycle_during_a_clients_connect_is_not_lost():
    """A cycle walked while the tracker is sending a new client its snapshot reaches that
    client: the snapshot and the registration are one step, as a publish sees them."""
    with SimStamp(SimConfig(tracker=("127.0.0.1", 0))) as sim:
        world, walkers = sim.world, []
        snapshot = world.snapshot

        def slow_snapshot():
            s = snapshot()
            t = threading.Thread(target=world.advance, args=(12, 0, None))
            walkers.append(t)
            t.start()
            t.join(0.3)  # the cycle is walked (and published) while this client is connecting
            return s

        world.snapshot = slow_snapshot
        with socket.create_connection(sim.tracker.address, timeout=3) as s:
            lines = _lines(s, 3)
        assert parse_pose(lines[1]).seq == 0
        assert (parse_pose(lines[2]).seq, parse_pose(lines[2]).gait) == (1, 12)
        walkers[0].join(3)
        assert len(walkers) == 1 and len(world.history) == 1


def test_tracker_noise_is_seeded():
    def observed(seed):
        with SimStamp(SimConfig(tracker_noise=(1.0, 1.0), seed=seed)) as sim:
            for i in range(5):
                sim.world.advance(12, i, 12 if i else None)
            return [h.observed for h in sim.world.history]

    assert observed(1) == observed(1) != observed(2)


def test_eeprom_survives_a_power_cycle(tmp_path, make_sim):
    path = tmp_path / "stamp.eeprom.json"
    sim, port = make_sim(eeprom=str(path))
    link = StampLink(port)
    link.hello()
    link.load([(7, 3), (22, 1)])
    sim.close()
    sim2, port2 = make_sim(eeprom=str(path))
    link2 = StampLink(port2)
    link2.hello()
    assert link2.status().count == 2
    link2.run(4)
    assert [c.gait for c in link2.wait_done()[0]] == [7, 7, 7, 22]


def test_bad_eeprom_file_is_one_clear_error(tmp_path):
    bad = tmp_path / "e.json"
    bad.write_text('{"format": "pac-sim-eeprom/1", "image": "zz"}')
    with pytest.raises(InputError, match="EEPROM file"):
        Eeprom(bad)


def test_closing_twice_leaves_other_emulators_alone(make_sim):
    sim, _ = make_sim()
    sim.close()
    sim2, port2 = make_sim()  # may reuse the first one's descriptor numbers
    sim.close()
    link = StampLink(port2)
    assert link.hello().protocol == 1
