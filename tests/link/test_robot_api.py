"""The typed robot API and PAL's linked robot against the emulator on a real pty."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.coverage import START_POSE, parse_turn_cycle, simulate
from pac_host.model import shifted_table
from pac_host.robot.api import RobotReset, RobotSilent, StampRobot
from pac_host.robot.linked import LinkedRobot
from pac_host.robot.observers import open_observer
from pac_host.robot.placement import TrackerPlacer
from pac_protocol.link import StampLink
from pac_protocol.port import open_port
from pac_sim.runner import SimConfig, SimStamp


@pytest.fixture
def sim_robot():
    made = []

    def make(**kw):
        sim = SimStamp(SimConfig(factor=0.0, tracker=("127.0.0.1", 0), **kw)).start()
        port = open_port(sim.path)
        robot = StampRobot(StampLink(port, name=sim.path, ready_timeout=0.5), event_timeout=0.5)
        robot.hello()
        made.append((sim, port))
        return sim, robot

    yield make
    for sim, port in made:
        port.close()
        sim.close()


def test_run_and_step_with_a_callback_per_gait_cycle(sim_robot):
    sim, robot = sim_robot()
    robot.load([(12, 2), (3, 1)])
    assert robot.stored() == [(12, 2), (3, 1)]
    seen = []
    rep = robot.run(7, lambda c: seen.append((c.gait, c.done)))
    assert rep.completed and rep.done == 7 and rep.power_on_before == 0
    assert seen == [(12, 1), (12, 2), (3, 3), (12, 4), (12, 5), (3, 6), (12, 7)]
    rep = robot.step(20, 3)
    assert rep.done == 3 and rep.power_on_before == 7 and robot.status().power_on == 10


def test_a_robot_that_stops_answering_mid_run(sim_robot):
    _, robot = sim_robot(mute_after=4)
    robot.load([(12, 5)])
    with pytest.raises(RobotSilent, match="stopped answering during a run of 9 gait cycles, "
                                          "after 4 reported") as e:
        robot.run(9)
    assert e.value.cycles == 4


def test_a_robot_that_resets_mid_run(sim_robot):
    _, robot = sim_robot(reset_after=3)
    robot.load([(12, 5)])
    with pytest.raises(RobotReset, match="reset during a run after 2 gait cycles"):
        robot.run(9)


def test_linked_robot_scores_the_observed_path(sim_robot, tmp_path):
    sim, robot = sim_robot(table="shifted")
    host, port = sim.tracker.address
    observer = open_observer(f"tracker:{host}:{port}")
    placer = TrackerPlacer(host, port)
    log = []
    linked = LinkedRobot(robot, observer, placer, 60, log.append, seed=3)
    heard = []
    linked.progress, linked.progress_every = (lambda *a: heard.append(a)), 25
    tests = np.stack([parse_turn_cycle("12:20,3:9"), parse_turn_cycle("27:5,0:0")])
    results = linked.run_tests(tests)
    # progress: each test as it starts and ends, the gait cycles walked every 25
    walked = [("gait cycles", n, 60) for n in (0, 25, 50)]
    assert heard == [("tests", 0, 2, "g0-t0"), *[w + ("g0-t0",) for w in walked],
                     ("tests", 1, 2, "g0-t0"), ("tests", 1, 2, "g0-t1"),
                     *[w + ("g0-t1",) for w in walked], ("tests", 2, 2, "g0-t1")]
    # noise-free tracker: the path and the figures are exactly the true robot's
    want = simulate(shifted_table().rows, tests, 60, (), START_POSE, keep_paths=True)
    for k, r in enumerate(results):
        assert np.allclose(r.poses, want.poses[k], atol=2e-3)  # 3 decimals on the wire
        assert (r.blocks_covered, r.fitness) == (want.blocks_covered[k], want.fitness[k])
    assert [r["run_id"] for r in linked.runs] == ["g0-t0", "g0-t1"]
    assert linked.runs[1]["cycles_since_power_on"] == 60
    assert sum(e["type"] == "pose" for e in log) == 120
    observer.close()
    placer.close()


def test_ctrl_c_during_a_run_stops_the_robot(sim_robot):
    sim, robot = sim_robot()
    robot.load([(12, 5)])

    def interrupt(c):
        if c.done == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        robot.run(500, interrupt)
    rep = robot.follow(500)  # the STOP was sent: the run ends at the next gait-cycle boundary
    assert not rep.completed and rep.done < 10
    assert robot.status().state == 0 and sim.stamp.cycles_total < 10
