"""Calibration: where the floor is in the image, where the camera is, and (optionally) its lens.

- The floor: a homography from ideal (undistorted) pixels to floor cm, fitted to the corners of
  at least four floor markers at known places (over one or more frames), with its reprojection
  error in cm.
- The camera's position (for the parallax of a marker above the floor): from the same corners
  with the lens's intrinsics (``cv2.solvePnP``); without a calibrated lens, the focal length is
  estimated from the homography (needs a camera that looks somewhat obliquely), or the height
  is given.
- The lens (optional): intrinsics and distortion from ChArUco board images
  (``cv2.aruco.CharucoDetector``, ``cv2.calibrateCamera``).

All of it is saved in one JSON file, ``{"format": "pac-camera-calibration/1", ...}``.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from pac_host.camera.detect import Corners, detect, make_detector
from pac_host.camera.geometry import undistort
from pac_host.camera.layout import DEFAULT_BOARD, DEFAULT_LAYOUT, Board, Layout, floor_corners
from pac_host.errors import InputError
from pac_host.files import write_atomic

FORMAT = "pac-camera-calibration/1"
MIN_FLOOR_MARKERS = 4
MIN_TILT_DEG = 6.0  # a view closer to square-on than this does not tell the focal length


@dataclass(frozen=True)
class Lens:
    K: np.ndarray
    dist: np.ndarray
    error_px: float  # RMS reprojection error of the board corners
    images: int


@dataclass(frozen=True)
class Calibration:
    size: tuple[int, int]
    layout: Layout
    H: np.ndarray  # ideal pixels -> floor cm
    center: np.ndarray  # the camera's lens, floor frame cm
    lens: Lens | None
    floor_error_cm: dict  # rms, max, markers (ids used), frames

    def ideal(self, pixels: np.ndarray) -> np.ndarray:
        if self.lens is None:
            return np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        return undistort(pixels, self.lens.K, self.lens.dist)

    def to_plane(self, pixels: np.ndarray, height: float = 0.0) -> np.ndarray:
        """Floor-frame (x, y) cm of pixels (n, 2) that show points ``height`` cm above the
        floor: through the homography to the floor, then along the ray back up to the height
        (the parallax of a marker above the floor)."""
        f = cv2.perspectiveTransform(self.ideal(pixels).reshape(-1, 1, 2), self.H).reshape(-1, 2)
        c = self.center
        return c[:2] + (f - c[:2]) * (c[2] - height) / c[2]

    def from_floor(self, points: np.ndarray, height: float = 0.0) -> np.ndarray:
        """Distorted pixels (n, 2) of floor-frame points (n, 2) at ``height``: the inverse of
        :meth:`to_plane` (for drawing)."""
        c = self.center
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        f = c[:2] + (p - c[:2]) * c[2] / (c[2] - height)
        ideal = cv2.perspectiveTransform(f.reshape(-1, 1, 2), np.linalg.inv(self.H))
        if self.lens is None:
            return ideal.reshape(-1, 2)
        K = self.lens.K
        norm = (ideal.reshape(-1, 2) - K[:2, 2]) / [K[0, 0], K[1, 1]]
        obj = np.column_stack([norm, np.ones(len(norm))]).reshape(-1, 1, 3)
        px, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), K, self.lens.dist)
        return px.reshape(-1, 2)

    def to_json(self) -> dict:
        doc = {"format": FORMAT, "image_size": list(self.size), "layout": self.layout.to_json(),
               "floor_homography": self.H.tolist(), "camera_center_cm": self.center.tolist(),
               "floor_error_cm": self.floor_error_cm, "lens": None}
        if self.lens is not None:
            doc["lens"] = {"K": self.lens.K.tolist(), "dist": self.lens.dist.tolist(),
                           "error_px": self.lens.error_px, "images": self.lens.images}
        return doc

    def save(self, path: Path) -> None:
        write_atomic(Path(path), json.dumps(self.to_json(), indent=1) + "\n")


def load(path: Path | str) -> Calibration:
    """A calibration file; InputError naming the file for anything else."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(f"calibration file {path} does not exist") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(f"{path}: not a camera calibration (not JSON: {e})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        kind = doc.get("format") if isinstance(doc, dict) else None
        raise InputError(f"{path}: not a camera calibration ({FORMAT}); "
                         f"it is {kind or 'another kind of file'}")
    try:
        lens = doc["lens"]
        return Calibration(
            (int(doc["image_size"][0]), int(doc["image_size"][1])),
            Layout.from_json(doc["layout"]),
            np.array(doc["floor_homography"], dtype=np.float64).reshape(3, 3),
            np.array(doc["camera_center_cm"], dtype=np.float64).reshape(3),
            None if lens is None else Lens(np.array(lens["K"], dtype=np.float64).reshape(3, 3),
                                           np.array(lens["dist"], dtype=np.float64).ravel(),
                                           float(lens["error_px"]), int(lens["images"])),
            dict(doc["floor_error_cm"]))
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise InputError(f"{path}: a damaged camera calibration ({e!r})") from None


# ---- the lens --------------------------------------------------------------------------------


def calibrate_lens(frames: Iterable[np.ndarray], board: Board = DEFAULT_BOARD,
                   min_images: int = 5) -> Lens:
    """Intrinsics and distortion from frames of the ChArUco board (at least ``min_images``
    showing at least 6 of its corners)."""
    cb = board.charuco()
    det = cv2.aruco.CharucoDetector(cb)
    obj, img, size = [], [], None
    for f in frames:
        size = (f.shape[1], f.shape[0])
        cc, ci, _, _ = det.detectBoard(f)
        if ci is None or len(ci) < 6:
            continue
        o, i = cb.matchImagePoints(cc, ci)
        obj.append(o.astype(np.float32))
        img.append(i.astype(np.float32))
    if len(obj) < min_images:
        raise InputError(f"the lens board was found in {len(obj)} image(s); need at least "
                         f"{min_images} (print the board sheet flat, fill the view with it)")
    err, K, dist, _, _ = cv2.calibrateCamera(obj, img, size, None, None,
                                            flags=cv2.CALIB_FIX_K3)
    return Lens(K, dist.ravel()[:5], float(err), len(obj))


# ---- the floor -------------------------------------------------------------------------------


def floor_observations(frames: Iterable[np.ndarray], layout: Layout) -> tuple[Corners, int]:
    """The median corners of each floor marker over the frames, and the frame count."""
    det = make_detector(layout.dictionary)
    known = layout.floor_by_id()
    seen: dict[int, list[np.ndarray]] = {}
    n = 0
    for f in frames:
        n += 1
        for i, c in detect(det, f).items():
            if i in known:
                seen.setdefault(i, []).append(c)
    return {i: np.median(np.array(cs), axis=0) for i, cs in seen.items()}, n


def focal_from_homography(H_floor_to_img: np.ndarray, principal: Sequence[float]) -> float | None:
    """The focal length (pixels) that makes the homography a rotation (square pixels, principal
    point known); None when the view is too square-on to tell."""
    T = np.array([[1, 0, principal[0]], [0, 1, principal[1]], [0, 0, 1.0]])
    A = np.linalg.inv(T) @ H_floor_to_img
    h1, h2 = A[:, 0], A[:, 1]
    a = np.array([h1[0] * h2[0] + h1[1] * h2[1], h1[0] ** 2 + h1[1] ** 2 - h2[0] ** 2 - h2[1] ** 2])
    b = np.array([h1[2] * h2[2], h1[2] ** 2 - h2[2] ** 2])
    w = -(a @ b) / (a @ a)
    if not w > 0:
        return None
    f = float(1 / np.sqrt(w))
    # a square-on view leaves both constraints near 0 = 0: too weak to trust
    M = np.diag([1 / f, 1 / f, 1.0]) @ A
    r3 = np.cross(M[:, 0] / np.linalg.norm(M[:, 0]), M[:, 1] / np.linalg.norm(M[:, 1]))
    tilt = np.degrees(np.arccos(min(1.0, abs(r3[2]) / np.linalg.norm(r3))))
    return f if tilt >= MIN_TILT_DEG else None


def calibrate_floor(frames: Iterable[np.ndarray], layout: Layout = DEFAULT_LAYOUT,
                    lens: Lens | None = None, camera_height: float | None = None
                    ) -> Calibration:
    """The floor homography and the camera's position from frames showing the floor markers."""
    frames = list(frames)
    if not frames:
        raise InputError("no frames to calibrate from")
    size = (frames[0].shape[1], frames[0].shape[0])
    obs, n = floor_observations(frames, layout)
    known = layout.floor_by_id()
    ids = sorted(obs)
    if len(ids) < MIN_FLOOR_MARKERS:
        missing = sorted(set(known) - set(ids))
        raise InputError(f"{len(ids)} of the {len(known)} floor markers seen (ids "
                         f"{ids or 'none'}; missing {missing}); need at least "
                         f"{MIN_FLOOR_MARKERS} to calibrate the floor")
    px = np.concatenate([obs[i] for i in ids])
    floor = np.concatenate([floor_corners(known[i]) for i in ids])
    ideal = undistort(px, lens.K, lens.dist) if lens is not None else px
    H, _ = cv2.findHomography(ideal, floor, 0)
    if H is None:
        raise InputError("the floor markers' corners give no homography (markers in a line?)")
    res = cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), H).reshape(-1, 2) - floor
    d = np.hypot(res[:, 0], res[:, 1])
    err = {"rms": round(float(np.sqrt((d ** 2).mean())), 4), "max": round(float(d.max()), 4),
           "markers": ids, "frames": n}
    center = camera_center(H, px, floor, size, lens, camera_height)
    return Calibration(size, layout, H, center, lens, err)


def camera_center(H: np.ndarray, px: np.ndarray, floor: np.ndarray, size: tuple[int, int],
                  lens: Lens | None, camera_height: float | None) -> np.ndarray:
    """Where the lens is (floor frame, cm): solvePnP with the lens (or the focal length the
    homography implies); a given height replaces the fitted one."""
    principal = ((size[0] - 1) / 2, (size[1] - 1) / 2)
    if lens is not None:
        K, dist = lens.K, lens.dist
    else:
        f = focal_from_homography(np.linalg.inv(H), principal)
        if f is None:
            if camera_height is None:
                raise InputError("the camera looks too squarely down to tell its height from "
                                 "the floor markers alone: give --camera-height CM or "
                                 "calibrate the lens (--lens)")
            nadir = cv2.perspectiveTransform(np.array([[principal]]), H).reshape(2)
            return np.array([nadir[0], nadir[1], camera_height])
        K = np.array([[f, 0, principal[0]], [0, f, principal[1]], [0, 0, 1]])
        dist = None
    obj = np.column_stack([floor, np.zeros(len(floor))])
    ok, rvec, tvec = cv2.solvePnP(obj, px, K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise InputError("cannot place the camera from the floor markers")
    R = cv2.Rodrigues(rvec)[0]
    c = (-R.T @ tvec).ravel()
    if c[2] <= 0:
        c = -c  # the mirror solution
    if camera_height is not None:
        c[2] = camera_height
    return c
