"""Recovery in layers on a damaged line: retries, a STATUS resync, a redone test, and a give-up
that is bounded in time. Faults are aimed at chosen frames, so each layer is reached on purpose."""

from __future__ import annotations

import time

import numpy as np
import pytest

from pac_host.coverage import START_POSE, parse_turn_cycle, simulate
from pac_host.errors import PacError
from pac_host.model import shifted_table
from pac_host.robot.api import StampRobot
from pac_host.robot.linked import LinkedRobot
from pac_host.robot.observers import open_observer
from pac_host.robot.placement import TrackerPlacer
from pac_host.robot.recovery import give_up_s
from pac_protocol.link import StampLink
from pac_protocol.port import open_port
from pac_sim.line import Faults
from pac_sim.runner import SimConfig, SimStamp
from pac_sim.targeted import parse_targets

from .conftest import SMALL, invoke, read_jsonl, results

READY_S, EVENT_S = 0.5, 0.5


@pytest.fixture
def rig():
    """An emulated robot with its tracker as observer and placer; faults as asked."""
    made = []

    def make(drop=(), corrupt=(), **kw):
        sim = SimStamp(SimConfig(factor=0.0, tracker=("127.0.0.1", 0),
                                 faults=Faults(targets=parse_targets(drop, corrupt)), **kw))
        sim.start()
        port = open_port(sim.path)
        robot = StampRobot(StampLink(port, name=sim.path, ready_timeout=READY_S), EVENT_S)
        robot.hello()
        host, tport = sim.tracker.address
        observer, placer = open_observer(f"tracker:{host}:{tport}"), TrackerPlacer(host, tport)
        made.append((sim, port, observer, placer))
        return sim, robot, observer, placer

    yield make
    for sim, port, observer, placer in made:
        observer.close()
        placer.close()
        port.close()
        sim.close()


TESTS = np.stack([parse_turn_cycle("12:20,3:9"), parse_turn_cycle("27:5,0:3")])


def true_results(budget: int):
    return simulate(shifted_table().rows, TESTS, budget, (), START_POSE, keep_paths=True)


def run_linked(rig, budget=60, **faults):
    sim, robot, observer, placer = rig(**faults)
    log: list[dict] = []
    linked = LinkedRobot(robot, observer, placer, budget, log.append, seed=3)
    return sim, linked, log, linked.run_tests(TESTS)


def test_a_false_report_is_dropped_not_counted(rig):
    """The out-of-step bug: a CYCLE report that lost a byte equal to A5 passes the check with
    a false power-on count. Here gait cycle 165 since power-on (the 45th of the second
    run of 120) loses its low power-on byte, A5. Before the fix the observer waited for a pose
    after gait cycle 121 of a 120-cycle run."""
    sim, linked, log, res = run_linked(rig, budget=120, drop=("CYCLE:165:8",))
    assert sim.line.aimed_out.hit == ["drop CYCLE:165:8"]
    want = true_results(120)
    for k, r in enumerate(res):  # exactly the true robot's paths (noise-free tracker)
        assert np.allclose(r.poses, want.poses[k], atol=2e-3)
    false = [e for e in log if e["type"] == "implausible_report"]
    assert len(false) == 1 and false[0]["run_id"] == "g0-t1"
    assert "done=45" in false[0]["report"] and "power_on=165" not in false[0]["report"]
    assert linked.recovery.implausible_reports == 1 and linked.recovery.redone_tests == 0


def test_retries_then_a_status_resync_then_the_request_again(rig):
    """Every reply to the first four READs lost: four attempts, then STATUS reads what the
    Stamp does, then the same READ (same SEQ) gets through."""
    sim, robot, _, _ = rig(drop=tuple(f"GENE_R:{k}:6" for k in range(1, 5)))
    robot.load([(7, 3)])
    events: list[dict] = []
    robot.link.on_event = events.append
    assert robot.link.read_gene(0).gait == 7
    kinds = [e["type"] for e in events]
    assert kinds.count("resync") == 1 == robot.link.stats.resyncs
    resync = events[kinds.index("resync")]
    assert resync["request"].startswith("READ") and resync["state"] == 0
    before = [e for e in events[: kinds.index("resync")] if e["request"].startswith("READ")]
    assert len(before) == 3  # attempts 2..4 of the first round
    assert sim.line.aimed_out.hit == [f"drop GENE_R:{k}:6" for k in range(1, 5)]


@pytest.mark.parametrize("boot", [(), ("BOOT:2:5",)], ids=["boot-heard", "boot-lost"])
def test_a_test_whose_robot_reset_mid_way_is_redone_from_its_start(rig, boot):
    """Reset after 30 gait cycles; with its BOOT report lost too, STATUS finds the robot idle
    with counts that cannot be this run's, twice: a reset all the same."""
    sim, linked, log, res = run_linked(rig, reset_after=30, drop=boot)
    want = true_results(60)
    for k, r in enumerate(res):
        assert np.allclose(r.poses, want.poses[k], atol=2e-3)
    redo = [e for e in log if e["type"] == "redo"]
    assert len(redo) == 1 and redo[0]["run_id"] == "g0-t0" and "RobotReset" in redo[0]["why"]
    starts = [e for e in log if e["type"] == "start"]
    assert [s.get("attempt", 0) for s in starts] == [0, 1, 0]  # placed again for the redo
    assert linked.recovery.redone_tests == 1
    # the redone test's poses are those of its second attempt, from the re-placed start
    assert linked.runs[0]["cycles_since_power_on"] == 0  # the reset restarted the count


def test_a_robot_switched_off_gives_up_within_the_stated_time(rig):
    """Muted after 10 gait cycles: the event timeout, STATUS (no READY: a dead line is not
    retried), then the redo's STOP and STATUS: at most EVENT_S + 3 READY_S after the last
    report, plus the emulator's pace; the error is today's, naming what was seen."""
    sim, robot, observer, placer = rig(mute_after=10)
    last = []
    linked = LinkedRobot(robot, observer, placer, 60, lambda d: None, seed=3)
    on_cycle = observer.on_cycle

    def seen(power_on):
        last.append(time.monotonic())
        on_cycle(power_on)

    observer.on_cycle = seen
    with pytest.raises(PacError, match="stopped answering during a run of 60 gait cycles, "
                                       "after 10 reported") as e:
        linked.run_tests(TESTS[:1])
    gave_up = time.monotonic() - last[-1]
    assert gave_up < give_up_s(EVENT_S, READY_S) + 1.0, gave_up
    assert "redoing the test" in str(e.value)


@pytest.mark.slow
def test_soak_at_1_percent_dropped_and_corrupted_bytes(baseline, tmp_path):
    """The short soak (the long one, 20 fault seeds, is `make bench`): 3 punctuations with 1%
    of the bytes dropped and 1% corrupted each way give exactly the clean run's decisions."""
    out = tmp_path / "soak"
    res = invoke("evolve", "--out", str(out), "--generations", "40", *SMALL,
                 "--drop-prob", "0.01", "--corrupt-prob", "0.01", "--sim-seed", "1")
    assert res.exit_code == 0, res.output
    assert results(out) == results(baseline)
    assert (out / "runs.jsonl").read_text() == (baseline / "runs.jsonl").read_text()
    log = read_jsonl(out / "log.jsonl")
    retries = sum(r["recovery"]["retries"] for r in log)
    assert retries > 0 and f"link recovery: {retries} retries" in res.output
    obs = read_jsonl(out / "observations.jsonl")
    assert sum(o["type"] == "retry" for o in obs) >= retries  # each one logged as it happened
    done = [o for o in obs if o["type"] == "done"]
    assert sum(o["lost_reports"] for o in done) > 0  # the faults really hit the reports


def test_measure_redoes_a_measurement_whose_robot_reset(rig):
    """`measure` uses the same layers: the reset in the second placement's walk is redone, and
    the fit is that of a clean line (the same run seeds, the same tracker noise)."""
    from pac_host.robot.connect import Connection
    from pac_host.robot.measure import MeasureConfig, measure
    from pac_host.robot.recovery import Recovery

    cfg = MeasureConfig(ids=(12, 20), repeats=2, cycles=3, seed=1)
    fits, recs = [], []
    for kw in ({}, {"reset_after": 5}):
        sim, robot, observer, placer = rig(tracker_noise=(0.5, 1.0), **kw)
        rec, log = Recovery(), []
        fits.append(measure(Connection(robot, observer, placer, "emulator"), cfg, log.append,
                            recovery=rec))
        recs.append((rec, log))
    assert [(f.gait, f.mean.tolist(), f.sd.tolist()) for f in fits[1]] == \
        [(f.gait, f.mean.tolist(), f.sd.tolist()) for f in fits[0]]
    rec, log = recs[1]
    assert rec.redone_tests == 1 and recs[0][0].redone_tests == 0
    assert [e["run_id"] for e in log if e["type"] == "redo"] == ["m12-r1"]
