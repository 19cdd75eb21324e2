"""The camera: observer and the POSE server: poses after each gait cycle from the frames of
its window, lost observations logged and kept as gaps (never made up), too many raised, what
was seen kept."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from pac_host.camera.observer import CameraObserver, CameraOptions, PoseFinder
from pac_host.camera.serve import PoseServer
from pac_host.camera.sources import RenderSource
from pac_host.robot.observers import ObserverError, open_observer

START = (45.0, 30.0, 90.0)


def _source(rig, path, start=START):
    """The virtual camera showing the robot at path[power_on - 1], before the run at ``start``
    (None: not in view)."""
    return RenderSource(rig[0], lambda key: start if key is None else path[key - 1], 0)


def test_observer_takes_each_cycles_pose_and_reports_a_lost_marker(rig):
    path = [(45.0, 30.0 + 10 * i, 90.0 - 15 * i) for i in range(4)] + [None]
    log = []
    obs = CameraObserver(_source(rig, path), rig[1],
                         CameraOptions(frames=2, retries=1, max_lost=0.1), "camera:test")
    obs.begin("r1", 0, log.append)
    for k in range(1, 6):
        obs.on_cycle(k)
    assert log[-1] == {"type": "lost", "run_id": "r1", "cycle": 5,
                       "why": "robot marker 0 not seen in 2 frame(s) (looked 2 times)"}
    with pytest.raises(ObserverError, match=r"lost observation of 1 of 5 gait cycles of run r1 "
                       r"\(more than 10% .*\); the last, gait cycle 5: robot marker 0 not seen"):
        obs.finish(5)  # one of five is more than a tenth
    poses = [r["pose"] for r in log if r["type"] == "pose" and r["cycle"] > 0]
    assert len(poses) == 4
    err = np.abs(np.array(poses) - np.array(path[:4]))
    assert err[:, :2].max() < 0.5 and err[:, 2].max() < 1.5  # unwrapped: 90 .. 45


def test_an_impossible_jump_is_lost_not_used(rig):
    path = [(45.0, 30.0, 90.0), (150.0, 250.0, 90.0)]
    log = []
    obs = CameraObserver(_source(rig, path), rig[1], CameraOptions(frames=1, retries=0),
                         "camera:test")
    obs.begin("r2", 0, log.append)
    obs.on_cycle(1)
    obs.on_cycle(2)
    assert [(r["type"], r["cycle"]) for r in log] == [("pose", 0), ("pose", 1), ("lost", 2)]
    assert "from its last pose" in log[-1]["why"]
    with pytest.raises(ObserverError, match="lost observation of 1 of 2 gait cycles"):
        obs.finish(2)


def test_the_start_pose_is_seen_before_the_first_gait_cycle(rig):
    """A hand placement leaves the robot off the nominal start: the camera sees where, with
    the instrument that sees every later pose; unseen, the run goes on from the placement."""
    start = (47.3, 28.6, 93.5)
    path = [(57.0, 29.5, 92.0), (69.0, 30.5, 91.0)]
    for opts, where, seen in ((CameraOptions(frames=2), start, True),
                              (CameraOptions(frames=2, start=0), start, False),
                              (CameraOptions(frames=2), None, False)):
        log = []
        obs = CameraObserver(_source(rig, path, where), rig[1], opts, "camera:test")
        obs.begin("s1", 0, log.append)
        for k in (1, 2):
            obs.on_cycle(k)
        got = obs.finish(2)
        assert len(got.poses) == 2
        at_start = [r for r in log if r.get("cycle") == 0]
        if seen:
            assert np.hypot(*np.subtract(got.start[:2], start[:2])) < 0.3
            assert abs(got.start[2] - start[2]) < 1.0
            assert [r["pose"] for r in at_start] == [[round(v, 4) for v in got.start]]
        else:
            assert got.start is None and not at_start
        assert [r["type"] for r in log].count("start_unseen") == (where is None)


def test_a_lost_cycle_report_is_a_lost_observation(rig):
    path = [(45.0, 30.0, 90.0)] * 3
    log = []
    obs = CameraObserver(_source(rig, path), rig[1], CameraOptions(frames=1), "camera:test")
    obs.begin("r3", 0, log.append)
    obs.on_cycle(1)
    obs.on_cycle(3)
    assert [r["cycle"] for r in log if r["type"] == "lost"] == [2]
    assert "CYCLE report was lost" in log[-2]["why"] and log[-1]["cycle"] == 3
    with pytest.raises(ObserverError, match="gait cycle 2: its CYCLE report was lost"):
        obs.finish(3)


def test_an_empty_window_is_a_stale_camera():
    class Stalled:
        name, live = "stalled", True

        def window(self, n, seconds, key=None):
            return []

        def close(self):
            pass

    from pac_host.camera.virtual import reference_rig

    obs = CameraObserver(Stalled(), reference_rig()[1], CameraOptions(), "camera:0")
    obs.begin("r4", 10, lambda _: None)
    for k in range(11, 19):  # eight gaps: a burst, not yet too many
        obs.on_cycle(k)
    with pytest.raises(ObserverError, match="lost observation of 9 of 9 gait cycles of run r4 "
                       ".* no fresh frame within 0.1 s"):
        obs.on_cycle(19)


def test_serve_feeds_the_tracker_observer(rig):
    """`camera serve` answers the tracker: observer's requests with poses, or LOST."""
    path = [(90.0, 100.0 + 8 * i, 0.0 + 20 * i) for i in range(3)] + [None]
    finder = PoseFinder(rig[1], CameraOptions(frames=2))
    server = PoseServer(_source(rig, path), finder)
    t = threading.Thread(target=server.serve, daemon=True)
    t.start()
    try:
        host, port = server.address
        obs = open_observer(f"tracker:{host}:{port}")
        try:
            log = []
            obs.begin("r5", 0, log.append)
            for k in (1, 2):
                obs.on_cycle(k)
            got = obs.finish(3).poses
            assert np.abs(got - np.array(path[:3]))[:, :2].max() < 0.5
            assert np.abs(got - np.array(path[:3]))[:, 2].max() < 1.5
            obs.begin("r6", 3, log.append)  # cycle 4: the robot has left the view
            obs.on_cycle(4)
            assert log[-1]["type"] == "lost" and "robot marker 0 not seen" in log[-1]["why"]
            with pytest.raises(ObserverError, match="lost observation of 1 of 1 gait cycles "
                               "of run r6"):
                obs.finish(1)
        finally:
            obs.close()
    finally:
        server.close()
        t.join(timeout=5)


def test_a_video_file_gives_frames_per_window(rig, tmp_path):
    """camera:VIDEO,calib=FILE,frames=2 reads two frames per gait cycle in order."""
    import cv2

    path = [(45.0 + 12 * i, 30.0, 90.0) for i in range(3)]
    video = tmp_path / "run.avi"
    out = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 30, (640, 480), False)
    rng = np.random.default_rng(4)
    for p in path:
        for _ in range(2):
            out.write(rig[0].frame(p, rng))
    out.release()
    calib = tmp_path / "calib.json"
    rig[1].save(calib)
    obs = open_observer(f"camera:{video},calib={calib},frames=2")
    assert not obs.sees_start  # a recording's frames are one window a gait cycle
    try:
        obs.begin("v1", 100, lambda _: None)
        for k in (101, 102):
            obs.on_cycle(k)
        got = obs.finish(3).poses
    finally:
        obs.close()
    assert np.abs(got - np.array(path))[:, :2].max() < 1.0
    assert np.abs(got - np.array(path))[:, 2].max() < 2.0


def test_the_virtual_cameras_noise_depends_on_the_run_alone(rig):
    """A resumed run sees the frames an uninterrupted one saw."""
    path = [(45.0, 30.0, 90.0), (57.0, 31.0, 88.0)]
    src = _source(rig, path)
    obs = CameraObserver(src, rig[1], CameraOptions(frames=1), "camera:test")

    def run(run_id):
        obs.begin(run_id, 0, lambda _: None)
        obs.on_cycle(1)
        return obs.finish(2).poses

    a, b = run("g40-t1"), run("g40-t2")
    assert np.array_equal(run("g40-t1"), a) and not np.array_equal(a, b)


def test_a_live_window_takes_only_fresh_frames():
    """Frames that arrived before the robot's report are stale: never used."""
    import time

    from pac_host.camera.sources import FrameBuffer

    buf = FrameBuffer()
    old = np.zeros((2, 2), np.uint8)
    buf.push(old)
    assert buf.window(3, 0.05) == []  # the camera stalled: nothing fresh
    new = np.ones((2, 2), np.uint8)

    def feed():
        for _ in range(5):
            time.sleep(0.01)
            buf.push(new)

    t = threading.Thread(target=feed)
    t.start()
    got = buf.window(3, 2.0)
    t.join()
    assert len(got) == 3 and all(g is new for g in got)
