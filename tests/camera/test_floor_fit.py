"""The floor from markers printed a little small and laid by hand (issue 63): the print scale
is fitted, not read as a floor error; with a calibrated lens the floor is the camera's pose's
(6 parameters, not a free homography's 8), which averages the markers' laying errors better;
neither the laying nor a near square-on view is blamed on the lens, while a lens that does not
fit the camera still is; the error map forecasts the fitted floor's error, not each marker's
laying, and a marker moved off its place is named. On the markers' corners projected through
known cameras (no rendering: fast)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from pac_host.camera.calibrate import Lens, calibrate_corners
from pac_host.camera.geometry import Camera, undistort
from pac_host.camera.layout import Layout, floor_corners, heading_rotation, square_corners
from pac_host.camera.render import standard_camera
from pac_host.errors import InputError

LAYOUT = Layout()
# a camera 3 m up looking 1.5 deg from straight down
DOWN = Camera.looking_at((1280, 720), 840.0, (90.0, 142.0, 300.0), (90.0, 150.0, 0.0), (0, 1, 0),
                         (0.0, 0.0, 0.0005, -0.0005, 0.0))


def _corners(cam: Camera, rng: np.random.Generator, scale: float = 1.0, cm: float = 0.0,
             deg: float = 0.0, noise: float = 0.1) -> dict[int, np.ndarray]:
    """The floor markers' corners in the image (distorted pixels, 0.1 px of noise): printed
    at ``scale``, each laid ``cm`` (sd per axis) and ``deg`` (sd) off its place."""
    out = {}
    for m in LAYOUT.floor:
        shift, turn = rng.normal(0.0, cm, 2), rng.normal(0.0, deg)
        floor = scale * square_corners(m.size) @ heading_rotation(turn).T + [m.x, m.y] + shift
        out[m.id] = cam.project(np.column_stack([floor, np.zeros(4)])) + rng.normal(0, noise,
                                                                                  (4, 2))
    return out


def _true_error(cal, cam: Camera, height: float = 12.0) -> float:
    """The calibration's RMS position error (cm) over a 10 cm grid of the area at the robot
    marker's height, against the camera's truth."""
    xs, ys = np.meshgrid(np.arange(0.0, 181.0, 10.0), np.arange(0.0, 301.0, 10.0))
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, height)])
    d = cal.to_plane(cam.project(pts), height) - pts[:, :2]
    return float(np.sqrt((d ** 2).sum(axis=1).mean()))


def _lens(cam: Camera, focal: float = 1.0) -> Lens:
    K = cam.K.copy()
    K[0, 0] *= focal
    K[1, 1] *= focal
    return Lens(K, cam.dist, 0.15, 12, size=cam.size)


def _check(cal, name: str) -> dict:
    return next(c for c in cal.checks if c["check"] == name)


def test_markers_laid_by_hand_are_averaged_through_the_cameras_pose():
    """Twelve labs, each laying the floor markers 3 mm (sd per axis) and 1 deg off by
    hand, printed 2 % small: the print scale is found each time, the lens is never blamed, and
    the floor is on average clearly closer to the truth than the free homography of the
    corners at their printed size (the fit before: 8 parameters follow the laying errors
    more)."""
    cam = standard_camera()
    lens = _lens(cam)
    ours, free = [], []
    for seed in range(12):
        obs = _corners(cam, np.random.default_rng(seed), scale=0.98, cm=0.3, deg=1.0)
        cal = calibrate_corners(obs, cam.size, LAYOUT, lens)
        assert cal.floor_error_cm["print_scale"] == pytest.approx(0.98, abs=0.005)
        assert _check(cal, "print_scale")["status"] == "ok"
        assert _check(cal, "camera_pose")["status"] == "ok", _check(cal, "camera_pose")
        assert _check(cal, "lens_floor")["status"] == "ok", _check(cal, "lens_floor")
        ids = sorted(obs)
        H, _ = cv2.findHomography(undistort(np.concatenate([obs[i] for i in ids]), cam.K,
                                            cam.dist),
                                  np.concatenate([floor_corners(m) for m in LAYOUT.floor]), 0)
        ours.append(_true_error(cal, cam))
        free.append(_true_error(replace(cal, H=H), cam))
    assert np.mean(ours) < 0.9 * np.mean(free) and np.mean(ours) < 0.2, (ours, free)


@pytest.mark.parametrize("cam", [standard_camera(), DOWN], ids=["tilted", "down"])
def test_the_error_map_forecasts_the_fitted_floor_not_each_markers_laying(cam):
    """Twelve labs laying the floor markers 3 mm (sd per axis) and 1 deg off by hand: their
    corners fit to about 0.4 cm RMS, mostly each marker's own misplacement, which the fit
    averages over the 22 markers. The error map forecasts the fitted floor's error: its
    median, on average over the labs, within a factor of 1.6 of the true floor error (counting
    the corners' misfit as an error between the markers too forecast 3-4 times it), and no
    calibration warns."""
    forecast, true = [], []
    for seed in range(12):
        obs = _corners(cam, np.random.default_rng(seed), scale=0.98, cm=0.3, deg=1.0)
        cal = calibrate_corners(obs, cam.size, LAYOUT, _lens(cam))
        assert not cal.warnings, cal.warnings
        assert cal.floor_error_cm["rms"] > 0.3 and cal.error_map["model_cm"] == 0
        forecast.append(cal.error_map["median_cm"])
        true.append(_true_error(cal, cam))
    ratio = np.mean(forecast) / np.sqrt(np.mean(np.square(true)))
    assert 1 / 1.6 < ratio < 1.6, (forecast, true)


@pytest.mark.parametrize("cm", [2.0, 6.0])
def test_a_marker_moved_off_its_place_is_named_warned_or_refused(cm):
    """Marker 11 moved along the floor (the others laid 3 mm and 1 deg off by hand): 2 cm is
    warned, naming it and its offset, and the error map widens with what it pulls the fit;
    6 cm is refused (the corners fit to more than 1 cm RMS), naming it too."""
    cam = standard_camera()
    obs = _corners(cam, np.random.default_rng(3), scale=0.98, cm=0.3, deg=1.0)
    laid = calibrate_corners(obs, cam.size, LAYOUT, _lens(cam))
    m = LAYOUT.floor_by_id()[11]
    obs[11] = cam.project(np.column_stack([floor_corners(m) + [0.0, cm], np.zeros(4)]))
    if cm > 5:
        with pytest.raises(InputError, match=r"marker 11 is seen \d\.\d\d cm from its place.*"
                                             r"lay marker 11 again"):
            calibrate_corners(obs, cam.size, LAYOUT, _lens(cam))
        return
    moved = calibrate_corners(obs, cam.size, LAYOUT, _lens(cam))
    check = _check(moved, "floor_error")
    assert check["status"] == "warn" and "marker 11 is seen 1." in check["text"]
    assert "lay marker 11 again" in check["advice"]
    assert moved.error_map["median_cm"] > laid.error_map["median_cm"]
    assert moved.error_map["median_cm"] > _true_error(moved, cam) / 1.5


def test_a_page_printed_small_is_a_print_scale_not_a_floor_error():
    """Fitted to the page (92 %): the corners still fit to their noise, the floor is as
    accurate as a true print's, and the calibration says how the sheets were printed."""
    cam = standard_camera()
    true = calibrate_corners(_corners(cam, np.random.default_rng(1)), cam.size, LAYOUT,
                             _lens(cam))
    small = calibrate_corners(_corners(cam, np.random.default_rng(1), scale=0.92), cam.size,
                              LAYOUT, _lens(cam))
    assert small.floor_error_cm["print_scale"] == pytest.approx(0.92, abs=0.003)
    assert small.floor_error_cm["rms"] < 1.5 * true.floor_error_cm["rms"] < 0.2
    assert _check(small, "floor_error")["status"] == "ok"
    warn = _check(small, "print_scale")
    scale = small.floor_error_cm["print_scale"]
    assert warn["status"] == "warn" and f"printed at {100 * scale:.1f} %" in warn["text"]
    assert "no fit to page" in warn["advice"]
    assert _true_error(small, cam) < 0.1


def test_a_lens_that_does_not_fit_is_still_caught_a_square_on_view_is_not_blamed():
    """A focal length 5 % off, on a camera tilted 20 deg: the floor markers fit the lens's
    camera worse than a free homography, and the calibration warns. Looking nearly straight
    down (1.5 deg), the floor alone cannot place the camera: no check blames the lens."""
    mid = (90.0, 150.0, 0.0)
    tilted = Camera.looking_at((640, 480), 380.0, (90.0, 150.0 - 240 * np.tan(np.radians(20)),
                                                   240.0), mid, (0, 1, 0),
                               (-0.12, 0.03, 0.0005, -0.0005, 0.0))
    obs = _corners(tilted, np.random.default_rng(2))
    assert _check(calibrate_corners(obs, tilted.size, LAYOUT, _lens(tilted)),
                  "lens_floor")["status"] == "ok"
    wrong = calibrate_corners(obs, tilted.size, LAYOUT, _lens(tilted, 1.05))
    check = _check(wrong, "lens_floor")
    assert check["status"] == "warn" and "the lens does not fit" in check["text"]
    # the floor's misfit is smooth, not the markers' own: the error map counts it everywhere
    assert wrong.error_map["model_cm"] > 0.2
    assert 1 / 1.5 < wrong.error_map["median_cm"] / _true_error(wrong, tilted) < 1.5
    down = DOWN
    for seed in range(6):
        obs = _corners(down, np.random.default_rng(seed), scale=0.98, cm=0.3, deg=1.0)
        cal = calibrate_corners(obs, down.size, LAYOUT, _lens(down))
        assert not {c["check"] for c in cal.warnings} & {"camera_pose", "lens_floor"}
        assert _true_error(cal, down) < 0.4
