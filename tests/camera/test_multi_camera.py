"""Several cameras on one floor frame (a rig), on rendered frames: a pose two cameras see is
fused (within a single camera's accuracy), one camera's is handed over, none's is lost (never
invented); the rig planned for a long area from the field of view and the height (the
numbers the docs give); `evolve --observer camera:sim --budget 200` walks the whole sweep in
view."""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.camera.observer import CameraObserver, CameraOptions, check_spec
from pac_host.camera.plan import (
    MARKER_PX,
    focal_px,
    fov_deg,
    plan_rig,
    strip_plan,
    view_corners,
)
from pac_host.camera.rig import RigFinder, RigSource, fuse
from pac_host.camera.sources import RenderSource
from pac_host.cli.main import main
from pac_host.errors import InputError
from pac_host.robot.observers import ObserverError, open_observer

ROOT = Path(__file__).resolve().parents[2]
OVERLAP = [(20.0, 312.0, 75.0), (100.0, 322.0, 160.0), (170.0, 332.0, -100.0),
           (60.0, 318.0, 10.0)]  # seen whole by both cameras of the pair


@pytest.fixture(scope="module")
def pair(rig):
    """Two virtual webcams 2.5 m up along y, their views of the marker overlapping 40 cm
    (y 300..340), each calibrated from its own frames (the reference lens: ``rig``)."""
    from pac_host.camera.virtual import virtual_rig

    return virtual_rig((1, 2))


def _frames(pair, pose, n, rng):
    return [[pair.renderer(k).frame(pose, rng) for _ in range(n)] for k in range(2)]


def test_two_cameras_fuse_within_a_single_cameras_accuracy(pair):
    finder = RigFinder(pair.calibrations, CameraOptions(), ["a", "b"])
    rng = np.random.default_rng(5)
    for truth in OVERLAP:
        frames = _frames(pair, truth, 2, rng)
        single = [f.in_window(fr, truth[2])[0] for f, fr in zip(finder.finders, frames,
                                                                 strict=True)]
        pose, used, why = finder.in_window(frames, truth[2])
        assert pose is not None and not why and used == 4 and set(finder.last) == {"a", "b"}
        err = [math.hypot(p[0] - truth[0], p[1] - truth[1]) for p in single]
        fused = math.hypot(pose[0] - truth[0], pose[1] - truth[1])
        assert fused <= max(err) + 1e-9 and fused < 0.5  # single camera: median <= 0.5 cm
        assert abs(pose[2] - truth[2]) <= max(abs(p[2] - truth[2]) for p in single) + 1e-9
        assert abs(pose[2] - truth[2]) < 1.0
        # weighted by each camera's expected error there (its error map)
        w = [1 / finder.last[k][3] ** 2 for k in ("a", "b")]
        assert np.allclose(pose[:2], np.average([p[:2] for p in single], axis=0, weights=w))


def test_fuse_averages_headings_on_the_circle():
    x, y, h = fuse([(0, 0, 179.0), (2, 0, -179.0)], [1.0, 1.0], 180.0)
    assert (x, y) == (1.0, 0.0) and abs(h - 180.0) < 1e-9
    assert abs(fuse([(0, 0, 10.0), (0, 0, 20.0)], [1.0, 2.0], 0.0)[2] - 12.0) < 0.05


def test_cameras_that_disagree_make_a_lost_observation(pair):
    """A camera bumped 3 cm after its calibration: the rig says so, it makes up no mean."""
    moved = pair.calibrations[1]
    shift = np.array([[1.0, 0, 0], [0, 1.0, 3.0], [0, 0, 1.0]])
    finder = RigFinder([pair.calibrations[0], replace(moved, H=shift @ moved.H)],
                       CameraOptions(), ["a", "b"])
    pose, _, why = finder.in_window(_frames(pair, OVERLAP[1], 1, np.random.default_rng(1)),
                                    90.0)
    assert pose is None and re.search(r"cameras a and b see robot marker 0 2\.\d cm and "
                                      r"0\.\d deg apart", why), why


def test_the_observer_fuses_hands_over_and_loses_the_robot(pair):
    """The robot walks from where both cameras see it into the second's view alone, then out
    of both: fused, handed over, then a lost observation logged and no pose made up."""
    path = [(100.0, 322.0 + 35 * i, 90.0) for i in range(13)]  # y 322 .. 742
    names = ["a", "b"]
    sources = [RenderSource(pair.renderer(k), lambda key: (100.0, 300.0, 90.0) if key is None
                            else path[key - 1], k) for k in range(2)]
    opts = CameraOptions(frames=1)
    finder = RigFinder(pair.calibrations, opts, names)
    obs = CameraObserver(finder.attach(RigSource(sources, names)), None, opts, "camera:test",
                         finder)
    log = []
    obs.begin("r1", 0, log.append)
    try:  # the lost gait cycles are gaps; as many as these may stop the test
        for k in range(1, len(path) + 1):
            obs.on_cycle(k)
        obs.finish(len(path))
    except ObserverError:
        pass
    seen = {r["cycle"]: r for r in log if r["type"] == "pose"}
    lost = [r for r in log if r["type"] == "lost"]
    # before the run the cameras near the start pose look (a), then those near the last pose
    assert set(seen[0]["cameras"]) == {"a"} and set(seen[1]["cameras"]) == {"a", "b"}
    handed = [i for i, r in seen.items() if set(r["cameras"]) == {"b"}]
    assert handed and min(handed) <= 4 and max(handed) >= 9
    for i, r in seen.items():
        truth = path[i - 1] if i else (100.0, 300.0, 90.0)
        assert math.hypot(r["pose"][0] - truth[0], r["pose"][1] - truth[1]) < 0.5
    assert lost and all(path[r["cycle"] - 1][1] > 650 for r in lost)
    assert not any(path[i - 1][1] > 680 for i in seen if i)  # nothing seen out of view
    assert "not seen" in lost[0]["why"]


def test_a_rig_of_recorded_folders_each_with_its_calibration(pair, tmp_path):
    """`camera:DIR1,calib=A.json+DIR2,calib=B.json`: each camera's frames, its own file."""
    path = [(100.0, 322.0, 90.0), (100.0, 357.0, 80.0), (100.0, 392.0, 70.0)]
    rng = np.random.default_rng(2)
    parts = []
    for k in range(2):
        d = tmp_path / f"cam{k}"
        d.mkdir()
        for i, pose in enumerate(path):
            cv2.imwrite(str(d / f"{i:03d}.png"), pair.renderer(k).frame(pose, rng))
        pair.calibrations[k].save(tmp_path / f"cam{k}.json")
        parts.append(f"{d},calib={tmp_path / f'cam{k}.json'}")
    obs = open_observer("camera:" + "+".join(parts) + ",frames=1")
    log = []
    obs.begin("r", 0, log.append)
    for k in range(1, 4):
        obs.on_cycle(k)
    got = obs.finish(3).poses
    obs.close()
    assert np.hypot(*(got[:, :2] - np.array(path)[:, :2]).T).max() < 0.5
    assert [len(r["cameras"]) for r in log if r["type"] == "pose"] == [2, 1, 1]


@pytest.mark.parametrize("spec,why", [
    ("a,calib=x.json+b", "camera:b: give calib=FILE"),
    ("a,calib=x.json,frames=2+b,calib=y.json,frames=3", "frames is given as 2 and 3"),
    ("a,calib=x.json+a,calib=y.json", "camera a is given twice"),
    ("a,calib=x.json,cameras=2x2", "cameras= is camera:sim's"),
    ("sim+a,calib=x.json", "joins no other camera"),
    ("sim,cameras=2", "expected 1 (the reference camera) or COLUMNSxROWS"),
    ("sim,calib=x.json,cameras=3x4", "calibrates the single reference camera"),
])
def test_rig_specs_refused_in_one_line(spec, why):
    with pytest.raises(InputError, match=re.escape(why)):
        check_spec(spec, emulated=True)


def test_rig_specs_accepted():
    for spec in ("a,calib=x.json+b,calib=y.json,frames=2", "sim", "sim,cameras=3x4,frames=1",
                 "sim,cameras=1", "sim,calib=x.json", "0,calib=a.json+1,calib=b.json+2,"
                 "calib=c.json,frames=2"):
        check_spec(spec, emulated=True)


# ---- the plan ------------------------------------------------------------------------------


def test_the_plan_for_a_long_area_from_the_field_of_view_and_the_height():
    plan = strip_plan(1000)  # a 640x480 webcam with a 75 deg field of view, 2.5 m up
    assert abs(fov_deg(focal_px(75.0, 640), 640) - 75.0) < 1e-9
    fx, fy = plan.footprint(0.0)
    assert abs(fy - 2 * 250 * math.tan(math.radians(37.5))) < 1e-9  # 2 h tan(fov / 2)
    assert abs(fx / fy - 480 / 640) < 1e-12
    corners = view_corners(plan, 0)  # the geometry's own pinhole agrees
    assert np.allclose(np.ptp(corners, axis=0), [fx, fy])
    assert (plan.cameras, len(plan.xs)) == (4, 1)
    assert plan.overlaps[1] >= 40
    # the marker it asks for spans what `camera sheets` asks (one definition), a cm less not
    need = plan.marker_needed
    assert need * plan.px_per_cm >= MARKER_PX > (need - 1) * plan.px_per_cm
    # the marker's plate, turned any way, is seen whole by some camera wherever on the area
    cams = [plan.camera(i) for i in range(plan.cameras)]
    r = plan.marker
    for x in (0.0, 90.0, 180.0):
        for y in np.linspace(0, 1000, 41):
            for h in (0.0, 45.0):
                a = np.radians(h)
                rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
                plate = (np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * r.plate / 2) @ rot.T
                pts = np.column_stack([plate + [x, y], np.full(4, r.height)])
                assert any(np.all((c.project(pts) >= -0.5 - 1e-6)
                                  & (c.project(pts) <= [639.5 + 1e-6, 479.5 + 1e-6]))
                           for c in cams), (x, y, h)  # inside the image's pixels
    # every camera sees at least 4 floor markers whole (to calibrate it), their ids one 4x4
    # dictionary's
    layout = plan.layout()
    assert plan.markers_seen(layout) >= 4 and len(layout.floor) == 70
    for c in cams:
        inside = [m for m in layout.floor if np.all(
            (c.project(np.array([[m.x + dx, m.y + dy, 0.0] for dx in (-8, 8)
                                 for dy in (-8, 8)])) >= 0)
            & (c.project(np.array([[m.x + dx, m.y + dy, 0.0] for dx in (-8, 8)
                                   for dy in (-8, 8)])) <= [639, 479]))]
        assert len(inside) >= 4
    # fewer cameras hung higher; a wider lens too
    assert plan_rig(plan.watched, height=350).cameras < plan.cameras
    assert plan_rig(plan.watched, fov=90).cameras < plan.cameras


def test_the_docs_give_the_plans_numbers():
    """docs/how-to/camera.md quotes `pac-host camera layout --length 1000`: the same lines."""
    text = (ROOT / "docs" / "how-to" / "camera.md").read_text()
    block = re.search(r"```text\n\$ pac-host camera layout --length 1000\n(.*?)```", text,
                      re.S)
    assert block is not None
    res = CliRunner().invoke(main, ["camera", "layout", "--length", "1000"])
    assert res.exit_code == 0, res.output
    assert block.group(1).strip().splitlines() == res.output.strip().splitlines()
    assert res.output.strip().splitlines() == strip_plan(1000).lines()


def test_camera_layout_writes_the_layout_the_calibration_reads(tmp_path):
    res = CliRunner().invoke(main, ["camera", "layout", "--length", "600", "--out",
                                    str(tmp_path)])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "layout.json").read_text())
    assert doc["watched"] == [0.0, 180.0, 0.0, 600.0] and len(doc["floor"]) == 2 * 21
    assert (tmp_path / "floor_plan.png").stat().st_size > 0
    res = CliRunner().invoke(main, ["camera", "layout", "--height", "40"])
    assert res.exit_code == 2 and "hang the cameras higher" in res.output


# ---- the whole sweep in view -----------------------------------------------------------------


@pytest.mark.slow
def test_evolve_through_the_virtual_rig_walks_200_gait_cycles_in_view(tmp_path):
    """A default run's first tests, on a model the robot does not fit yet, walk 200 gait
    cycles far off the area's first 300 cm (x to 627, y to 1214): the rig sees every one."""
    out = tmp_path / "rig"
    res = CliRunner().invoke(main, [str(a) for a in (
        "evolve", "--out", out, "--budget", "200", "--generations", "0",
        "--initial-generations", "20", "--cga-population", "32", "--model-population", "16",
        "--search-evaluations", "20000", "--seed", "0", "--observer",
        "camera:sim,cameras=3x4,frames=1")])
    assert res.exit_code == 0, res.output
    runs = [json.loads(x) for x in (out / "runs.jsonl").read_text().splitlines()]
    poses = np.concatenate([r["poses"] for r in runs])
    assert len(runs) == 3 and len(poses) == 600 and np.isfinite(poses).all()
    assert poses[:, 1].max() > 840 and poses[:, 0].max() > 226  # beyond one camera's view
    seen = [json.loads(x) for x in (out / "observations.jsonl").read_text().splitlines()]
    cams = [len(o["cameras"]) for o in seen if o["type"] == "pose"]
    assert not [o for o in seen if o["type"] == "lost"]
    assert min(cams) == 1 and max(cams) >= 2  # handed over and fused
