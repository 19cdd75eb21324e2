"""Poses detected in rendered frames against the truth: the calibration, the parallax of the
raised marker, poses along a real turn cycle in pac-sim's world, headings across 360 deg."""

from __future__ import annotations

import numpy as np

from pac_host.camera.detect import detect
from pac_host.camera.layout import floor_corners
from pac_host.camera.observer import CameraOptions, PoseFinder, wrap180
from pac_host.coverage import START_POSE
from pac_host.model import resolve_table
from pac_sim.world import World


def _errors(rig, poses, finder, frames=1, seed=0):
    renderer, _ = rig
    rng = np.random.default_rng(seed)
    pos, head = [], []
    for p in poses:
        got, used, why = finder.in_window([renderer.frame(p, rng) for _ in range(frames)],
                                          float(p[2]))
        assert got is not None, (p, why)
        pos.append(np.hypot(got[0] - p[0], got[1] - p[1]))
        head.append(abs(wrap180(got[2] - p[2])))
    return np.array(pos), np.array(head)


def test_calibration_recovers_the_camera_and_reports_its_error(rig):
    renderer, calib = rig
    cam = renderer.camera
    assert np.linalg.norm(calib.center - cam.center) < 3.0  # cm, at 2.5 m
    assert abs(calib.lens.K[0, 0] - cam.K[0, 0]) / cam.K[0, 0] < 0.01
    e = calib.floor_error_cm
    assert len(e["markers"]) == len(calib.layout.floor) == 22
    assert 0 < e["rms"] < 0.3 and e["max"] < 0.6
    # the homography puts every floor marker's corners where they are
    frame = renderer.frame(None, np.random.default_rng(5))
    finder = PoseFinder(calib, CameraOptions())
    seen = detect(finder.detector, frame)
    for m in calib.layout.floor:
        err = np.hypot(*(calib.to_plane(seen[m.id]) - floor_corners(m)).T)
        assert err.max() < 0.6, (m.id, err)


def test_poses_along_a_turn_cycle_in_pac_sims_world(rig):
    """pac-sim's world walks the shifted robot through a turn cycle; the camera sees each
    pose within the targets (median 0.5 cm, 1 deg)."""
    world = World(resolve_table("shifted"), start=START_POSE)
    gaits = [12, 12, 3, 3, 3, 3, 12, 19, 19, 19, 19, 12, 12, 7, 7, 7, 12, 12]
    prev = None
    for i, g in enumerate(gaits):
        world.advance(g, i, prev)
        prev = g
    truth = [s.true_pose for s in world.history]
    finder = PoseFinder(rig[1], CameraOptions())
    pos, head = _errors(rig, truth, finder)
    assert np.median(pos) <= 0.5 and np.median(head) <= 1.0, (pos, head)
    assert pos.max() < 1.5 and head.max() < 4


def test_parallax_of_the_raised_marker_is_corrected(rig):
    """Near the area's corners a marker 12 cm up shows several cm off if taken on the floor."""
    poses = [(5.0, 5.0, 30.0), (175.0, 295.0, -60.0), (175.0, 5.0, 200.0), (5.0, 295.0, 95.0)]
    right, _ = _errors(rig, poses, PoseFinder(rig[1], CameraOptions()))
    floor, _ = _errors(rig, poses, PoseFinder(rig[1], CameraOptions(height=0.0)))
    assert right.max() < 0.6
    assert floor.min() > 3.0


def test_heading_is_unwrapped_near_the_reference(rig):
    finder = PoseFinder(rig[1], CameraOptions())
    rng = np.random.default_rng(3)
    got, _, _ = finder.in_window([rig[0].frame((90, 150, 719.0), rng)], 700.0)
    assert abs(got[2] - 719.0) < 1.5
    got, _, _ = finder.in_window([rig[0].frame((90, 150, -181.0), rng)], -170.0)
    assert abs(got[2] + 181.0) < 1.5


def test_without_a_lens_calibration_the_homography_places_the_camera():
    """A lens without distortion needs no board: the focal length comes from the tilted
    floor's homography; a camera looking straight down needs its height given."""
    import pytest

    from pac_host.camera.calibrate import calibrate_floor
    from pac_host.camera.geometry import Camera
    from pac_host.camera.render import Renderer, standard_camera
    from pac_host.errors import InputError

    rng = np.random.default_rng(2)
    tilted = standard_camera(dist=(0, 0, 0, 0, 0))
    cal = calibrate_floor([Renderer(tilted).frame(None, rng)])
    assert cal.lens is None and np.linalg.norm(cal.center - tilted.center) < 10
    down = Camera.looking_at((640, 480), 420.0, (90, 150, 250), (90, 150, 0), (0, 1, 0))
    frame = Renderer(down).frame(None, rng)
    with pytest.raises(InputError, match="give --camera-height"):
        calibrate_floor([frame])
    cal = calibrate_floor([frame], camera_height=250.0)
    assert np.linalg.norm(cal.center - down.center) < 2
