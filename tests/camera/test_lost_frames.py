"""Issue 63: frames of real cameras (motion blur, JPEG, noise, patchy light, markers printed
small and laid by hand), small blurred markers still read, a robot still walking never taken
for one standing, and a gait cycle that cannot be seen a gap in the test, not its end."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.camera.detect import detect, fit_square, make_detector
from pac_host.camera.geometry import Camera
from pac_host.camera.layout import Layout, RobotMarker
from pac_host.camera.observer import CameraObserver, CameraOptions, image_change, wrap180
from pac_host.camera.render import (
    Imaging,
    Printing,
    Renderer,
    light_field,
    line_kernel,
    random_walk,
    standard_camera,
)
from pac_host.camera.sheets import MARKER_PX, floor_px_per_cm, suggest_marker_size
from pac_host.camera.sources import RenderSource
from pac_host.cli.main import main
from pac_host.coverage.gaps import fill_gaps, seen_stretches
from pac_host.diagnose.runs import parse_runs
from pac_host.learning import model_fit, model_ga, pal
from pac_host.model import measured_table, shifted_table
from pac_host.robot.linked import observed_runs

# what testers' real-camera frames had: at 12 cm a quarter of the windows were lost
WEBCAM = Imaging(motion_blur=3.0, blur=1.0, noise=4.0, jpeg=60, light_field=0.3)
SUGGESTED = 17.0  # suggest_marker_size for the reference camera (checked below)


@pytest.fixture(scope="module")
def webcam():
    """The reference camera's frames through WEBCAM, the robot marker at the suggested size;
    and the 12 cm marker's renderer."""
    cam = standard_camera()
    big = RobotMarker(size=SUGGESTED, plate=SUGGESTED + 4)
    return (Renderer(cam, Layout(robot=big), WEBCAM), big,
            Renderer(cam, Layout(), WEBCAM))


def _calib(rig, robot: RobotMarker):
    """The reference calibration with the robot marker of another size (same floor)."""
    return replace(rig[1], layout=replace(rig[1].layout, robot=robot))


# ---- the renderer's real-camera options -----------------------------------------------------


def test_line_kernel_and_light_field():
    k = line_kernel(6.0, (1.0, 0.0))
    assert k.sum() == pytest.approx(1.0)
    yy, xx = np.mgrid[:k.shape[0], :k.shape[1]] - k.shape[0] // 2
    assert (k * xx ** 2).sum() == pytest.approx(36 / 12, rel=0.1) and (k * yy ** 2).sum() < 0.1
    f = light_field((64, 48), 0.3, seed=2)
    assert f.shape == (48, 64) and 0.7 <= f.min() and f.max() <= 1.3 and f.std() > 0.02
    assert np.abs(np.diff(f, axis=1)).max() < 0.05  # smooth
    assert np.array_equal(f, light_field((64, 48), 0.3, seed=2))


def test_motion_blur_smears_along_the_robots_motion_and_jpeg_compresses():
    cam = standard_camera((320, 240))  # small: quick to set up
    sharp = Renderer(cam, Layout(), Imaging(noise=0, blur=0.0))
    moving = Renderer(cam, Layout(), Imaging(noise=0, blur=0.0, motion_blur=3.0))
    pose = (90.0, 150.0, 30.0)
    base = sharp.frame(pose).astype(np.float64)
    u, v = cam.project(np.array([[90.0, 150.0, 12.0]]))[0].astype(int)
    box = np.s_[v - 15:v + 15, u - 15:u + 15]

    def energy(img):  # gradient energy along the image's x and y near the robot
        img = img.astype(np.float64)[box]
        return np.abs(np.diff(img, axis=1)).sum(), np.abs(np.diff(img, axis=0)).sum()

    bx, by = energy(base)
    # compass 0 (+y on the floor) runs along the image's width, compass 90 across it
    ax, ay = energy(moving.frame(pose, motion=0.0))
    cx, cy = energy(moving.frame(pose, motion=90.0))
    assert ax / bx < 0.8 * (ay / by) and cy / by < 0.8 * (cx / bx)
    assert np.array_equal(sharp.frame(None), moving.frame(None))  # the floor stands still
    jpeg = Renderer(cam, Layout(), Imaging(noise=0, blur=0.0, jpeg=50)).frame(pose)
    d = np.abs(jpeg.astype(np.float64) - base)
    assert 0 < d.mean() < 3


def test_markers_printed_small_and_laid_by_hand(rig):
    cam = standard_camera()
    laid = Renderer(cam, Layout(), Imaging(noise=0),
                    Printing(scale=0.95, placement_cm=0.5, placement_deg=2.0, seed=1))
    frame = laid.frame((90.0, 150.0, 0.0))
    det = make_detector(Layout().dictionary)
    seen = detect(det, frame)
    calib = rig[1]
    robot = fit_square(calib.to_plane(seen[0], 12.0), 12.0)
    assert robot.scale == pytest.approx(0.95, abs=0.01)  # printed 5 % small
    off = []
    for m in calib.layout.floor:
        if m.id not in seen:
            continue
        c = calib.to_plane(seen[m.id], 0.0)
        off.append((np.hypot(*(c.mean(axis=0) - (m.x, m.y))),
                    fit_square(c, m.size).scale))
    off = np.array(off)
    assert len(off) >= 8 and 0.1 < off[:, 0].max() < 2.5 and np.allclose(off[:, 1], 0.95, atol=0.02)


# ---- detection of small blurred markers, and the marker's size ------------------------------


def test_the_marker_size_for_a_camera_is_suggested(tmp_path):
    fov = 74.6
    ppc = floor_px_per_cm((640, 480), 250.0, fov, z=12.0)
    focal = 320 / np.tan(np.radians(fov / 2))
    down = Camera.looking_at((640, 480), focal, (90, 150, 250), (90, 150, 0), (0, 1, 0))
    px = down.project(np.array([[85.0, 150.0, 12.0], [95.0, 150.0, 12.0]]))
    assert np.linalg.norm(px[1] - px[0]) / 10 == pytest.approx(ppc, rel=1e-3)
    size = suggest_marker_size((640, 480), 250.0, fov)
    assert size == SUGGESTED and size * ppc >= MARKER_PX > (size - 0.5) * ppc
    assert suggest_marker_size((1280, 960), 250.0, fov) == 8.5
    res = CliRunner().invoke(main, ["camera", "sheets", "--out", str(tmp_path), "--resolution",
                                    "640x480", "--camera-height", "250", "--fov", "74.6"])
    assert res.exit_code == 0, res.output
    assert "1.76 px per cm" in res.output and "needs 17 cm for 30 px" in res.output
    robot = json.loads((tmp_path / "layout.json").read_text())["robot"]
    assert robot["size"] == 17 and robot["plate"] == 21
    bad = CliRunner().invoke(main, ["camera", "sheets", "--out", str(tmp_path), "--fov", "70"])
    assert bad.exit_code != 0 and "all of --resolution, --camera-height and --fov" in bad.output


def test_small_blurred_markers_are_read_where_opencv_alone_loses_them(rig, webcam):
    """At the far end of the reference view a 12 cm marker is 15-18 px across; with 3 px of
    motion blur OpenCV finds the square but cannot read its bits in about half the frames."""
    small = webcam[2]
    det = make_detector(Layout().dictionary)
    rng = np.random.default_rng(4)
    opencv = ours = 0
    for _ in range(12):
        x, y, h = rng.uniform(10, 170), rng.uniform(275, 295), rng.uniform(-180, 180)
        frame = small.frame((x, y, h), rng)
        opencv += 0 in detect(det, frame)
        c = detect(det, frame, refine=(0,), find=0).get(0)
        if c is not None:
            p = fit_square(rig[1].to_plane(c, 12.0), 12.0)
            assert np.hypot(p.x - x, p.y - y) < 1.0 and abs(wrap180(p.h - h)) < 5
            ours += 1
    assert opencv <= 9 and ours >= 11
    for _ in range(5):  # never a robot where there is none
        assert 0 not in detect(det, small.frame(None, rng), find=0)


# ---- a robot still walking, and lost windows -----------------------------------------------


def _observe(renderer, calib, path, walking=0.0, finish=True, **opts):
    log: list[dict] = []
    source = RenderSource(renderer, lambda k: path[0] if k is None else path[k - 1], 3,
                          walking=walking)
    obs = CameraObserver(source, calib, CameraOptions(**opts), "camera:test")
    obs.begin("w0", 0, log.append)
    for k in range(1, len(path) + 1):
        obs.on_cycle(k)
    return (obs.finish(len(path)).poses if finish else None), log


def test_windows_at_3px_of_blur_with_the_suggested_marker_are_seen(rig, webcam):
    """The issue's target on a modest number of gait cycles: at most 5 % of the windows give
    no pose at the first look (bench/bench_camera_degraded.py measures more), none is a gap
    after the retries, every pose within a centimetre."""
    renderer, big, _ = webcam
    path = random_walk(40, np.random.default_rng(6))
    poses, log = _observe(renderer, _calib(rig, big), path, frames=3)
    again = [r for r in log if r["type"] == "pose" and r.get("looks", 1) > 1]
    assert len(again) <= 2 and not [r for r in log if r["type"] == "lost"]
    err = np.hypot(*(poses[:, :2] - np.array(path)[:, :2]).T)
    assert np.isfinite(poses).all() and np.median(err) < 0.3 and err.max() < 1.0


def test_a_robot_still_walking_is_looked_at_again(rig, webcam):
    """Every gait cycle's first window catches the robot 0.7 cm a frame before it stops:
    1.4 cm over the window, which the old 2 cm agreement passed. The still check rejects it;
    without retries each is a gap, with them the robot is seen standing."""
    renderer, big, _ = webcam
    calib = _calib(rig, big)
    path = random_walk(5, np.random.default_rng(7))
    _, log = _observe(renderer, calib, path, walking=1.0, finish=False, frames=3, retries=0,
                      max_lost=0.99)
    lost = [r for r in log if r["type"] == "lost"]
    assert len(lost) == 5 and not [r for r in log if r["type"] == "pose" and r["cycle"]]
    assert all("the robot moved during the window" in r["why"] for r in lost)
    poses, log = _observe(renderer, calib, path, walking=1.0, frames=3)
    seen = [r for r in log if r["type"] == "pose" and r["cycle"] > 0]
    assert [r["looks"] for r in seen] == [2] * 5
    assert np.hypot(*(poses[:, :2] - np.array(path)[:, :2]).T).max() < 0.5
    # the image alone shows it: a frame whose marker was not read counts too
    rng = np.random.default_rng(8)
    x, y, h = path[0]
    a, b = renderer.frame((x, y, h), rng), renderer.frame((x, y, h), rng)
    moved = renderer.frame((x + 0.7 * np.sin(np.radians(h)), y + 0.7 * np.cos(np.radians(h)),
                            h), rng)
    u, v = calib.from_floor(np.array([[x, y]]), big.height)[0].astype(int)
    box = (u - 25, v - 25, u + 25, v + 25)
    assert image_change(a, b, box) < 2.0 < 2.5 < image_change(a, moved, box)


# ---- gaps: the test goes on, the fit uses what was seen -------------------------------------


def test_a_path_with_gaps_is_filled_for_its_figures_and_split_for_the_fit():
    path = np.array([[45, 30, 90], [55, 30, 90], [np.nan] * 3, [75, 30, 90], [np.nan] * 3,
                     [np.nan] * 3, [105, 30, 90], [115, 30, 90]], dtype=np.float64)
    assert seen_stretches(path) == [(0, 1), (6, 7)]
    np.testing.assert_allclose(fill_gaps(path)[:, 0], np.arange(45, 125, 10))
    gaits = [12] * 7
    runs = observed_runs("g0-t1", path[0], gaits, path[1:], 40)
    assert [(r["run_id"], r["part_of"], len(r["poses"]), r["cycles_since_power_on"])
            for r in runs] == [("g0-t1-c0", "g0-t1", 1, 40), ("g0-t1-c6", "g0-t1", 1, 46)]
    parsed = parse_runs([json.dumps(r) for r in runs])  # the diagnosis reads them
    assert parsed[1].start_pose.tolist() == [105, 30, 90]
    whole = observed_runs("g0-t2", path[0], gaits, np.nan_to_num(path[1:]), 0)
    assert len(whole) == 1 and whole[0]["run_id"] == "g0-t2" and "part_of" not in whole[0]


def test_pal_learns_from_a_robot_seen_with_gaps():
    """A tenth of each test's gait cycles unseen: the punctuation runs, the record marks the
    estimated figures, the fit uses the steps seen (and still finds the robot's table), and
    the state keeps the gaps (null in its JSON)."""
    fit = pal.PALConfig(cga_population=24, model_population=8, generations=40, interval=20,
                        model_generations=0, correction="fit", tests="informative",
                        operational="tested", budget=100)
    truth = pal.SimulatedRobot(shifted_table(), budget=100)
    lost = np.random.default_rng(1).choice(np.arange(1, 101), 10, replace=False)

    class Gappy:
        def run_tests(self, tests):
            out = []
            for r in truth.run_tests(tests):
                p = r.poses.copy()
                p[lost] = np.nan
                out.append(replace(r, poses=p))
            return out

    rng = np.random.default_rng(5)
    state = pal.initial_state(measured_table(), rng, fit)
    state, rec = pal.punctuate(state, Gappy(), rng, fit)
    assert [o["gaps"] for o in rec["observed"]] == [10, 10, 10]
    assert np.abs(state.models[0] - shifted_table().rows).max() < 1e-6
    assert [int(np.isnan(o.poses).any(axis=1).sum()) for o in state.observed] == [10] * 3
    doc = json.loads(json.dumps(pal.state_to_json(state, rng), allow_nan=False))  # gaps: null
    again, _ = pal.state_from_json(doc)
    assert all(np.array_equal(a.poses, b.poses, equal_nan=True)
               for a, b in zip(again.observed, state.observed, strict=True))
    # the steps' error leaves the unseen steps out; a step seen is scored as before
    tc = np.array([[12, 20], [3, 8], [19, 6]])
    tests = tc[None]
    whole = truth.run_tests(tests)[0].poses
    gappy = whole.copy()
    gappy[[5, 50]] = np.nan
    off = measured_table().rows[None]
    e_whole = model_ga.step_error(tests, [whole], 100)(off)[0]
    e_gappy = model_ga.step_error(tests, [gappy], 100)(off)[0]
    assert np.isfinite(e_gappy) and e_gappy == pytest.approx(e_whole, rel=0.1)
    parts = model_fit.seen_parts(model_fit.Observed(model_fit.expand_ids(tc, 100), gappy))
    assert [len(p.gait_ids) for p in parts] == [4, 43, 49]
    assert [p.cycles_since_power_on for p in parts] == [0, 6, 51]


def test_the_observer_keeps_gaps_and_goes_on(rig):
    path = [(45.0, 30.0 + 10 * i, 90.0) for i in range(12)]
    hidden = {3, 7}  # the marker not in view for these gait cycles (a person in the way)
    source = RenderSource(rig[0], lambda k: path[0] if k is None else
                          (None if k in hidden else path[k - 1]), 0)
    log: list[dict] = []
    obs = CameraObserver(source, rig[1], CameraOptions(frames=1, retries=1), "camera:test")
    obs.begin("g1-t0", 0, log.append)
    for k in range(1, 13):
        obs.on_cycle(k)
    poses = obs.finish(12).poses
    gaps = ~np.isfinite(poses).all(axis=1)
    assert np.flatnonzero(gaps).tolist() == [2, 6]
    assert [r["cycle"] for r in log if r["type"] == "lost"] == [3, 7]
    assert np.abs(poses[~gaps] - np.array(path)[~gaps]).max() < 1.5
