"""Calibration: where the floor is in the image, where the camera is, and (optionally) its lens.

- The floor: a homography from ideal (undistorted) pixels to floor cm, fitted by least squares
  to the corners of at least four floor markers at known places (over one or more frames),
  with its reprojection error in cm. The markers' common print scale is fitted with it (a
  printer that shrinks the page moves every corner towards its marker's centre, not the
  centres; :func:`fit_floor`). With a calibrated lens the homography is the one the camera's
  pose implies (6 parameters: where the camera is and how it is turned, ``cv2.solvePnP`` on
  all the corners), not a free one (8): it uses what the lens board measured, so the floor
  markers' laying errors (a few mm by hand) are averaged over more markers per parameter, and
  the floor and the parallax correction come from one camera.
- The camera's position (for the parallax of a marker above the floor): from the same corners
  with the lens's intrinsics (``cv2.solvePnP``); without a calibrated lens, the focal length is
  estimated from the homography (needs a camera that looks somewhat obliquely), or the height
  is given.
- The lens (optional): intrinsics and distortion from ChArUco board images
  (``cv2.aruco.CharucoDetector``, ``cv2.calibrateCamera`` started from several plausible focal
  lengths; the distortion model with k3 only where it clearly fits better).

Each fitted quantity is checked (:mod:`pac_host.camera.quality`): a calibration that fails a
check is refused (InputError), its warnings are kept in the file's ``quality`` list with the
position error to expect over the area (``pose_error_map``).

All of it is saved in one JSON file, ``{"format": "pac-camera-calibration/1", ...}``; its
``lens`` section stands alone (its own image size), so a later floor calibration can reuse it
(:func:`load_lens`). :func:`load` is the one reader: anything but a sound calibration is one
line (InputError).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from pac_host.camera import quality as q
from pac_host.camera.detect import Corners, detect, make_detector
from pac_host.camera.geometry import undistort
from pac_host.camera.layout import (
    DEFAULT_BOARD,
    DEFAULT_LAYOUT,
    Board,
    Layout,
    dictionary,
    square_corners,
)
from pac_host.errors import InputError
from pac_host.files import write_atomic

FORMAT = "pac-camera-calibration/1"
MIN_FLOOR_MARKERS = 4
MIN_TILT_DEG = 6.0  # a view closer to square-on than this does not tell the focal length
START_FOV_DEG = (50.0, 75.0, 100.0, 125.0)  # the lens fit's starting fields of view
K3_GAIN = 0.9  # k3 is kept when it lowers the lens's RMS below this share of the simpler's
SIMPLE_MODEL, RICH_MODEL = "k1,k2,p1,p2", "k1,k2,p1,p2,k3"


@dataclass(frozen=True)
class Lens:
    K: np.ndarray
    dist: np.ndarray
    error_px: float  # RMS reprojection error of the board corners
    images: int
    model: str = SIMPLE_MODEL  # the distortion coefficients fitted
    size: tuple[int, int] | None = None  # the images' (width, height)
    coverage: float | None = None  # the share of the image the board's corners spanned
    model_rms: dict | None = None  # each model tried: its RMS (px)

    def checks(self, size: tuple[int, int] | None = None,
               cm_per_px: float | None = None) -> list[dict]:
        size = size or self.size
        model = self.model + "".join(f"; {k}: {v:.3f} px" for k, v in (self.model_rms or {})
                                     .items() if k != self.model)
        return q.lens_checks(self.K, self.dist, size, self.error_px, self.images, model,
                             self.coverage, cm_per_px)

    def to_json(self) -> dict:
        doc = {"K": self.K.tolist(), "dist": np.ravel(self.dist).tolist(),
               "error_px": self.error_px, "images": self.images, "model": self.model}
        if self.size is not None:
            doc["image_size"] = list(self.size)
        if self.coverage is not None:
            doc["coverage"] = round(self.coverage, 4)
        if self.model_rms:
            doc["model_rms_px"] = self.model_rms
        return doc


@dataclass(frozen=True)
class Calibration:
    size: tuple[int, int]
    layout: Layout
    H: np.ndarray  # ideal pixels -> floor cm
    center: np.ndarray  # the camera's lens, floor frame cm
    lens: Lens | None
    floor_error_cm: dict  # rms, max, markers (ids used), frames
    checks: tuple[dict, ...] = ()  # the quality report (quality.check dicts)
    error_map: dict | None = None  # quality.pose_error_map

    @property
    def warnings(self) -> list[dict]:
        return q.warnings(self.checks)

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
               "floor_error_cm": self.floor_error_cm,
               "lens": None if self.lens is None else self.lens.to_json(),
               "quality": list(self.checks)}
        if self.error_map is not None:
            doc["pose_error_map"] = self.error_map
        return doc

    def save(self, path: Path) -> None:
        write_atomic(Path(path), json.dumps(self.to_json(), indent=1) + "\n")


# ---- the one reader ----------------------------------------------------------------------------


class _Bad(Exception):
    """What is wrong with a calibration file (becomes one InputError naming the file)."""


def _non_finite(v, where: str = "") -> str | None:
    """Where the document holds a NaN or an infinity, if it does."""
    if isinstance(v, float) and not math.isfinite(v):
        return f"{where or 'the file'} is {v}"
    items = v.items() if isinstance(v, dict) else enumerate(v) if isinstance(v, list) else ()
    for k, x in items:
        found = _non_finite(x, f"{where}[{k}]" if isinstance(k, int) else
                            f"{where}.{k}" if where else str(k))
        if found:
            return found
    return None


def _get(doc: dict, key: str, where: str = ""):
    if not isinstance(doc, dict):
        raise _Bad(f"{where or 'the file'} is not an object")
    if key not in doc:
        raise _Bad(f"no {(where + '.' if where else '') + key}")
    return doc[key]


def _number(v, name: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise _Bad(f"{name} is {v!r}, not a finite number")
    return float(v)


def _array(v, shape: tuple[int, ...] | None, name: str) -> np.ndarray:
    """Numbers in nested lists of exactly ``shape`` (None: a flat list of any length)."""
    a = np.asarray(v, dtype=object) if isinstance(v, list) else None
    want = "a list of numbers" if shape is None else "x".join(map(str, shape)) + " numbers"
    if a is None or (a.shape != shape if shape is not None else a.ndim != 1):
        got = "a " + type(v).__name__ if a is None else "shape " + "x".join(map(str, a.shape))
        raise _Bad(f"{name} must be {want}, got {got}")
    return np.array([_number(x, name) for x in a.ravel()], dtype=np.float64).reshape(a.shape)


def _size(v, name: str = "image_size") -> tuple[int, int]:
    """[width, height] pixels, or the text "WIDTHxHEIGHT"."""
    if isinstance(v, str):
        m = re.fullmatch(r"\s*(\d+)\s*[xX*]\s*(\d+)\s*", v)
        if m is None:
            raise _Bad(f"{name} {v!r} is not [width, height] nor \"WIDTHxHEIGHT\"")
        w, h = int(m[1]), int(m[2])
    elif isinstance(v, list) and len(v) == 2:
        w, h = (_number(x, name) for x in v)
        if not (w.is_integer() and h.is_integer()):
            raise _Bad(f"{name} {v!r} is not whole pixels")
        w, h = int(w), int(h)
    else:
        raise _Bad(f"{name} must be [width, height] in pixels (or \"WIDTHxHEIGHT\"), got {v!r}")
    if not (16 <= w <= 100_000 and 16 <= h <= 100_000):
        raise _Bad(f"{name} {w}x{h} is not an image size")
    return w, h


def _lens(doc, size: tuple[int, int] | None) -> Lens:
    """The ``lens`` section; ``size`` is the file's image size (a lens without its own)."""
    K = _array(_get(doc, "K", "lens"), (3, 3), "lens.K")
    if not (K[0, 0] > 0 and K[1, 1] > 0 and np.allclose(K[2], [0, 0, 1])
            and K[1, 0] == 0 and abs(K[0, 1]) <= 0.01 * K[0, 0]):
        raise _Bad("lens.K is not a camera matrix ([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "
                   "fx, fy > 0)")
    dist = _array(_get(doc, "dist", "lens"), None, "lens.dist")
    if len(dist) not in (4, 5, 8, 12, 14):
        raise _Bad(f"lens.dist has {len(dist)} coefficients (OpenCV's: 4, 5, 8, 12 or 14)")
    err = _number(_get(doc, "error_px", "lens"), "lens.error_px")
    images = _number(_get(doc, "images", "lens"), "lens.images")
    if err < 0 or images < 1 or not images.is_integer():
        raise _Bad(f"lens.error_px {err:g} or lens.images {images:g} out of range")
    own = _size(doc["image_size"], "lens.image_size") if "image_size" in doc else None
    if own is None and size is None:
        raise _Bad("no lens.image_size")
    if own is not None and size is not None and own != size:
        raise _Bad(f"the lens was calibrated on {own[0]}x{own[1]} images, the floor on "
                   f"{size[0]}x{size[1]}")
    model = doc.get("model", SIMPLE_MODEL if len(dist) == 4 or dist[4] == 0 else RICH_MODEL)
    coverage = doc.get("coverage")
    coverage = None if coverage is None else _number(coverage, "lens.coverage")
    tried = doc.get("model_rms_px")
    if tried is not None and not (isinstance(tried, dict) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in tried.values())):
        raise _Bad("lens.model_rms_px must map models to numbers")
    lens = Lens(K, dist, err, int(images), str(model), own or size, coverage, tried)
    q.refuse(lens.checks(), "lens refused")
    return lens


def _read(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"calibration file {path} does not exist") from None
    except UnicodeDecodeError as e:
        raise InputError(f"{path}: not a camera calibration (not UTF-8 text: byte "
                         f"0x{e.object[e.start]:02x} at offset {e.start})") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read the camera calibration "
                         f"({e.strerror or e})") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not a camera calibration (not JSON: {e})") from None
    except RecursionError:
        raise InputError(f"{path}: not a camera calibration (nested too deeply)") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        kind = doc.get("format") if isinstance(doc, dict) else None
        raise InputError(f"{path}: not a camera calibration ({FORMAT}); "
                         f"it is {kind if isinstance(kind, str) else 'another kind of file'}")
    bad = _non_finite(doc)
    if bad:
        raise InputError(f"{path}: a damaged camera calibration: {bad}; calibrate again")
    return doc


def _checked(path: Path, fun):
    try:
        return fun()
    except _Bad as e:
        raise InputError(f"{path}: a damaged camera calibration: {e}; calibrate again") from None
    except InputError as e:
        raise InputError(f"{path}: {e}") from None


def load_lens(path: Path | str) -> Lens:
    """The lens section of a calibration file (to calibrate the floor again with it)."""
    path = Path(path)
    doc = _read(path)

    def lens():
        sec = _get(doc, "lens")
        if sec is None:
            raise InputError("the calibration holds no lens (it was made without --lens)")
        return _lens(sec, _size(_get(doc, "image_size")))

    return _checked(path, lens)


def load(path: Path | str) -> Calibration:
    """A calibration file, checked as :func:`calibrate_floor` checks a new one; InputError
    (one line naming the file) for anything else."""
    path = Path(path)
    doc = _read(path)
    return _checked(path, lambda: _calibration(doc))


def _calibration(doc: dict) -> Calibration:
    size = _size(_get(doc, "image_size"))
    lay = _get(doc, "layout")
    if not isinstance(lay, dict):
        raise _Bad("layout is not an object")
    layout = Layout.from_json(lay)
    dictionary(layout.dictionary)
    r = layout.robot
    if not (all(m.size > 0 for m in layout.floor) and r.size > 0 and r.plate >= r.size
            and r.height >= 0) or len({m.id for m in layout.floor}) != len(layout.floor):
        raise _Bad("layout: marker sizes must be > 0, ids distinct, the robot's height >= 0")
    H = _array(_get(doc, "floor_homography"), (3, 3), "floor_homography")
    center = _array(_get(doc, "camera_center_cm"), (3,), "camera_center_cm")
    sec = _get(doc, "lens")
    lens = None if sec is None else _lens(sec, size)
    err = _get(doc, "floor_error_cm")
    rms = _number(_get(err, "rms", "floor_error_cm"), "floor_error_cm.rms")
    mx = _number(_get(err, "max", "floor_error_cm"), "floor_error_cm.max")
    markers = _get(err, "markers", "floor_error_cm")
    frames = _get(err, "frames", "floor_error_cm")
    if not (isinstance(markers, list) and all(isinstance(i, int) for i in markers)
            and isinstance(frames, int) and frames >= 1 and 0 <= rms <= mx + 1e-9):
        raise _Bad("floor_error_cm: rms <= max, markers a list of ids, frames >= 1")
    _check_homography(H, size, lens)
    x, y, z = center
    checks = [q.floor_check(rms, mx, None, lens is not None)]
    checks += q.height_check(z, None, lens is not None)
    q.refuse(checks)
    if max(abs(x), abs(y)) > 10_000:
        raise _Bad(f"camera_center_cm ({x:g}, {y:g}) is more than 100 m from the area")
    if not z > r.height + 1:
        raise _Bad(f"the robot's marker ({r.height:g} cm up) is not below the camera")
    stored = doc.get("quality", [])
    if not (isinstance(stored, list) and all(isinstance(c, dict) and isinstance(
            c.get("status"), str) and isinstance(c.get("text"), str) for c in stored)):
        raise _Bad("quality must be a list of checks (status, text)")
    emap = doc.get("pose_error_map")
    return Calibration(size, layout, H, center, lens, dict(err), tuple(stored),
                       emap if isinstance(emap, dict) else None)


def _check_homography(H: np.ndarray, size: tuple[int, int], lens: Lens | None) -> None:
    """A homography that maps the whole image onto the floor, in front of the camera."""
    w, h = size
    # in units of the image (0..1) to units of the area (~3 m): a sound one is well conditioned
    M = np.diag([1 / 300, 1 / 300, 1.0]) @ H @ np.diag([w, h, 1.0])
    s = np.linalg.svd(M, compute_uv=False)
    if not s[0] > 0 or s[-1] / s[0] < 1e-9:
        raise _Bad("floor_homography is singular (all zero?)")
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1], [w / 2, h / 2]],
                       dtype=np.float64)
    ideal = corners if lens is None else undistort(corners, lens.K, lens.dist)
    den = np.column_stack([ideal, np.ones(len(ideal))]) @ H[2]
    if not (np.all(den > 0) or np.all(den < 0)) or np.abs(den).min() < 1e-12 * np.abs(den).max():
        raise _Bad("floor_homography puts the horizon inside the image (not a floor seen "
                   "from above)")


# ---- the lens --------------------------------------------------------------------------------


def calibrate_lens(frames: Iterable[np.ndarray], board: Board = DEFAULT_BOARD,
                   min_images: int = 5) -> Lens:
    """Intrinsics and distortion from frames of the ChArUco board (at least ``min_images``
    showing at least 6 of its corners); refused (InputError) if the fit fails a check."""
    cb = board.charuco()
    det = cv2.aruco.CharucoDetector(cb)
    obj, img, size = [], [], None
    for f in frames:
        if size is not None and (f.shape[1], f.shape[0]) != size:
            raise InputError(f"the lens board images differ in size ({size[0]}x{size[1]}, "
                             f"{f.shape[1]}x{f.shape[0]})")
        size = (f.shape[1], f.shape[0])
        cc, ci, _, _ = det.detectBoard(f)
        if ci is None or len(ci) < 6:
            continue
        o, i = cb.matchImagePoints(cc, ci)
        obj.append(o.astype(np.float32))
        img.append(i.astype(np.float32))
    if len(obj) < min_images:
        raise InputError(f"the lens board was found in {len(obj)} image(s); need at least "
                         f"{min_images} (print the board sheet flat; hold it closer, "
                         "spanning a third to a half of the image's width)")
    lens = fit_lens(obj, img, size)
    q.refuse(lens.checks(), "lens calibration refused")
    return lens


def _plausible(K: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> bool:
    return (q.FOV_DEG[0] <= q.fov_deg(K[0, 0], size[0]) <= q.FOV_DEG[1]
            and abs(K[0, 0] / K[1, 1] - 1) <= q.ASPECT[1]
            and not q.radial_folds(K, dist, size))


def fit_lens(obj: Sequence[np.ndarray], img: Sequence[np.ndarray], size: tuple[int, int]
             ) -> Lens:
    """``cv2.calibrateCamera`` on the board's corners, started from several plausible focal
    lengths (the one ``cv2.initCameraMatrix2D`` reads off the views, and fields of view
    across the plausible range; principal point at the centre) so that a strong lens does
    not end in a false minimum; the best plausible fit with k1, k2 (k3 fixed at 0), then
    k3 freed from it and kept only if it lowers the RMS clearly."""
    w, h = size
    try:
        guess = float(cv2.initCameraMatrix2D(obj, img, size)[0, 0])
    except cv2.error:
        guess = float("nan")
    focals = [guess] if q.FOV_DEG[0] <= q.fov_deg(guess, w) <= q.FOV_DEG[1] else []
    focals += [f for f in (q.focal_for_fov(a, w) for a in START_FOV_DEG)
               if all(abs(f / g - 1) > 0.1 for g in focals)]

    def fit(K0: np.ndarray, d0: np.ndarray, flags: int):
        try:
            err, K, d, _, _ = cv2.calibrateCamera(obj, img, size, K0.copy(), d0.copy(),
                                                  flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS)
        except cv2.error:  # degenerate views: no fit from this start
            return float("inf"), K0, d0, False
        d = d.ravel()[:5]
        return float(err), K, d, _plausible(K, d, size)

    best = None
    for f in focals:
        K0 = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
        got = fit(K0, np.zeros(5), cv2.CALIB_FIX_K3)
        if best is None or (got[3], -got[0]) > (best[3], -best[0]):
            best = got
    err, K, d, ok = best
    rich = fit(K, d, 0)
    rms = {SIMPLE_MODEL: round(err, 4), RICH_MODEL: round(rich[0], 4)}
    if rich[3] and rich[0] < K3_GAIN * err:
        err, K, d, _ = rich
        model = RICH_MODEL
    else:
        model = SIMPLE_MODEL
    pts = np.concatenate([i.reshape(-1, 2) for i in img]).astype(np.float32)
    coverage = cv2.contourArea(cv2.convexHull(pts)) / (w * h)
    return Lens(K, d, err, len(obj), model, (w, h), float(coverage), rms)


# ---- the floor -------------------------------------------------------------------------------


def floor_observations(frames: Iterable[np.ndarray], layout: Layout) -> tuple[Corners, int]:
    """The median corners of each floor marker over the frames, and the frame count."""
    det = make_detector(layout.dictionary)
    known = layout.floor_by_id()
    seen: dict[int, list[np.ndarray]] = {}
    n = 0
    for f in frames:
        n += 1
        found = detect(det, f)
        for i, c in found.items():
            if i in known and not _inside_another(c, i, found):
                seen.setdefault(i, []).append(c)
    return {i: np.median(np.array(cs), axis=0) for i, cs in seen.items()}, n


def _inside_another(c: np.ndarray, i: int, found: Corners) -> bool:
    """Whether marker ``i``'s centre lies inside another marker found: a misread of that
    marker's bits, never a marker of its own."""
    centre = tuple(float(v) for v in c.mean(axis=0))
    return any(j != i and cv2.pointPolygonTest(o.astype(np.float32).reshape(-1, 1, 2), centre,
                                               False) > 0 for j, o in found.items())


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


def fit_floor(ideal: np.ndarray, layout: Layout, ids: Sequence[int],
              iterations: int = 3) -> tuple[np.ndarray | None, float, np.ndarray]:
    """The free homography (ideal pixels -> floor cm) of the floor markers ``ids`` from their
    corners ``ideal`` (4 per marker, in ``ids``' order), by least squares over all of them,
    and the scale the markers were printed at, fitted with it: each marker's corners lie
    around its centre at ``scale`` times its size in the layout (one scale for all: one
    printer). Returns the homography (None: the corners give none), the scale, and the
    corners' floor positions (cm) at that scale."""
    known = layout.floor_by_id()
    offsets = np.concatenate([square_corners(known[i].size) for i in ids])
    centres = np.repeat(np.array([[known[i].x, known[i].y] for i in ids], dtype=np.float64),
                        4, axis=0)
    scale = 1.0
    for k in range(iterations + 1):
        H, _ = cv2.findHomography(ideal, centres + scale * offsets, 0)
        if H is None or k == iterations:
            break
        # the corners on the floor about their marker's centre, against the printed shape
        m = cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), H).reshape(-1, 4, 2)
        o = (m - m.mean(axis=1, keepdims=True)).reshape(-1, 2)
        scale = float((o * offsets).sum() / (offsets * offsets).sum())
    return H, scale, centres + scale * offsets


def pose_homography(K: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The homography (ideal pixels -> floor cm) of a camera of intrinsics ``K`` at pose
    ``R``, ``t`` (floor -> camera frame): the inverse of K [r1 r2 t]."""
    H = np.linalg.inv(K @ np.column_stack([R[:, 0], R[:, 1], np.ravel(t)]))
    return H / H[2, 2]


def calibrate_floor(frames: Iterable[np.ndarray], layout: Layout = DEFAULT_LAYOUT,
                    lens: Lens | None = None, camera_height: float | None = None
                    ) -> Calibration:
    """The floor homography and the camera's position from frames showing the floor markers,
    checked (refused with InputError on a failed check) and with the position error to expect
    over the area. With a lens, the homography is the camera's pose's (:func:`camera_pose`);
    without, the free one of :func:`fit_floor`."""
    frames = list(frames)
    if not frames:
        raise InputError("no frames to calibrate from")
    size = (frames[0].shape[1], frames[0].shape[0])
    obs, n = floor_observations(frames, layout)
    return calibrate_corners(obs, size, layout, lens, camera_height, n)


def calibrate_corners(obs: Corners, size: tuple[int, int], layout: Layout = DEFAULT_LAYOUT,
                      lens: Lens | None = None, camera_height: float | None = None,
                      frames: int = 1) -> Calibration:
    """:func:`calibrate_floor` from the floor markers' corners seen (id -> 4 distorted pixel
    corners, OpenCV's order) over ``frames`` frames of ``size`` (width, height)."""
    n = frames
    known = layout.floor_by_id()
    ids = sorted(i for i in obs if i in known)
    if len(ids) < MIN_FLOOR_MARKERS:
        missing = sorted(set(known) - set(ids))
        raise InputError(f"{len(ids)} of the {len(known)} floor markers seen (ids "
                         f"{ids or 'none'}; missing {missing}); need at least "
                         f"{MIN_FLOOR_MARKERS} to calibrate the floor")
    px = np.concatenate([obs[i] for i in ids])
    ideal = undistort(px, lens.K, lens.dist) if lens is not None else px
    free, scale, floor = fit_floor(ideal, layout, ids)
    if free is None:
        raise InputError("the floor markers' corners give no homography (markers in a line?)")
    pose = camera_pose(free, px, floor, size, lens, camera_height)
    H = free if lens is None else pose_homography(lens.K, pose["R"], pose["t"])
    res = cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), H).reshape(-1, 2) - floor
    d = np.hypot(res[:, 0], res[:, 1])
    back = cv2.perspectiveTransform(floor.reshape(-1, 1, 2), np.linalg.inv(H)).reshape(-1, 2)
    rms_px = float(np.sqrt(((back - ideal) ** 2).sum(1).mean()))
    # a smooth misfit of the camera's model (beyond what chance explains), and each marker's
    # own offset from its place: its corners' mean residual, less that misfit where it counts
    model = q.smooth_misfit(ideal, floor, res, 8 if lens is None else 6, size, free)
    off = np.hypot(*q.marker_offsets(model["residuals"] if model["cm"] > 0 else res).T)
    err = {"rms": round(float(np.sqrt((d ** 2).mean())), 4), "max": round(float(d.max()), 4),
           "markers": ids, "frames": n, "print_scale": round(scale, 4),
           "worst_marker": [ids[int(np.argmax(off))], round(float(off.max()), 4)]}
    cm_per_px = float(np.median([known[i].size / np.linalg.norm(
        obs[i] - np.roll(obs[i], 1, axis=0), axis=1).mean() for i in ids]))
    checks = []
    if lens is not None:
        checks += lens.checks(size, cm_per_px) + q.lens_size_check(lens.size, size)
    else:
        checks.append(q.no_lens_check())
    checks.append(q.floor_check(err["rms"], err["max"], rms_px, lens is not None,
                                tuple(err["worst_marker"])))
    checks.append(q.print_scale_check(scale))
    if pose["focal"] is not None:
        checks.append(q.focal_check(pose["focal"], size[0]))
    checks += q.height_check(None if pose["fitted"] is None else float(pose["fitted"][2]),
                             camera_height, lens is not None, layout.robot.height)
    if lens is not None:
        checks.append(q.pose_check(pose["fitted"], pose["floor"], layout.robot.height,
                                   pose["floor_sigma"]))
        loose = cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), free).reshape(-1, 2) - floor
        checks.append(q.lens_floor_check(res, loose))
    q.refuse(checks)
    cal = Calibration(size, layout, H, pose["center"], lens, err)
    # the forecast: the fitted floor's uncertainty (each marker's corners erring together),
    # the robot marker's corners as noisy as this camera finds the lens board's (without a
    # lens, as the floor markers' corners scatter about their own marker), and a smooth misfit
    # of the camera's model beyond chance
    noise_px = lens.error_px if lens is not None else _corner_noise_px(res, floor, obs, ids,
                                                                      known)
    emap = q.pose_error_map(cal, floor_covariance(H, ideal, floor, pose, lens),
                            _center_sigma(pose, camera_height), max(noise_px, 0.05),
                            model["cm"])
    checks.append(q.map_check(emap, lens is not None))
    q.refuse(checks)
    return replace(cal, checks=tuple(checks), error_map=emap)


def floor_covariance(H: np.ndarray, ideal: np.ndarray, floor: np.ndarray, pose: dict,
                     lens: Lens | None) -> np.ndarray:
    """The covariance (8, 8) of the fitted floor's homography parameters, each marker's
    corners erring together (:func:`quality.cluster_covariance`): with a lens, of the camera's
    pose (6 parameters, fitted on the corners' pixels), carried to the homography; without,
    of the free homography (8, fitted on the floor)."""
    if lens is None:
        return q.cluster_covariance(*q.homography_fit(H, ideal, floor))
    K = lens.K
    theta = np.concatenate([cv2.Rodrigues(pose["R"])[0].ravel(), np.ravel(pose["t"])])
    obj = np.column_stack([floor, np.zeros(len(floor))])
    px, jac = cv2.projectPoints(obj, theta[:3], theta[3:], K, None)
    cov = q.cluster_covariance(jac[:, :6], (px.reshape(-1, 2) - ideal).ravel())

    def h_of(th):
        return q._h_params(pose_homography(K, cv2.Rodrigues(th[:3])[0], th[3:]))

    Jh = q._jacobian(h_of, theta)
    return Jh @ cov @ Jh.T


def _corner_noise_px(res: np.ndarray, floor: np.ndarray, obs: Corners, ids: Sequence[int],
                     known: dict) -> float:
    """The floor markers' corners' noise (pixels, sd per axis): their residuals about their
    own marker's shift and turn (:func:`quality.within_marker_noise`), through each marker's
    cm per pixel."""
    rem = q.within_marker_noise(res, floor).reshape(-1, 4, 2)
    cm_px = np.array([known[i].size / np.linalg.norm(obs[i] - np.roll(obs[i], 1, axis=0),
                                                     axis=1).mean() for i in ids])
    return float(np.sqrt(((rem / cm_px[:, None, None]) ** 2).sum() / (5 * len(ids))))


def _center_sigma(pose: dict, given: float | None) -> np.ndarray:
    """The camera centre's uncertainty per axis (cm): with a lens, how much farther its centre
    and the floor markers' lie apart than the floor markers' own uncertainty (twice its sd)
    explains (at least 0.5 % of the height); else GIVEN_HEIGHT_SIGMA of the height; a given
    height at least as far as the fitted one."""
    c = pose["center"]
    if pose["floor"] is not None:
        apart = np.abs(pose["fitted"] - pose["floor"]) - 2 * pose["floor_sigma"]
        s = np.maximum(apart, 0.005 * c[2])
    else:
        s = np.full(3, (0.01 if pose["lens"] else q.GIVEN_HEIGHT_SIGMA) * c[2])
    if given is not None and pose["fitted"] is not None:
        s[2] = max(s[2], abs(given - pose["fitted"][2]))
    return s


def camera_pose(H: np.ndarray, px: np.ndarray, floor: np.ndarray, size: tuple[int, int],
                lens: Lens | None, camera_height: float | None) -> dict:
    """Where the lens is (floor frame, cm): ``center``, from solvePnP with the lens (or the
    focal length the homography implies: ``focal``) and a given height in place of the fitted
    one; ``fitted``, solvePnP's centre (None when the view is too square-on to fit it without
    a lens); ``floor``, with a lens, the centre the floor markers alone imply (the focal
    length of the floor's perspective of ``H``, the free homography; None when too
    square-on); ``R``, ``t``, solvePnP's pose (floor -> camera frame; None without one)."""
    principal = ((size[0] - 1) / 2, (size[1] - 1) / 2)
    focal = floor_centre = floor_sigma = None
    if lens is not None:
        K, dist = lens.K, lens.dist
        floor_centre, floor_sigma = floor_alone_centre(
            H, q.homography_covariance(H, undistort(px, K, dist), floor, group=4), K[:2, 2])
    else:
        focal = focal_from_homography(np.linalg.inv(H), principal)
        if focal is None:
            if camera_height is None:
                raise InputError("the camera looks too squarely down to tell its height from "
                                 "the floor markers alone: give --camera-height CM or "
                                 "calibrate the lens (--lens)")
            nadir = cv2.perspectiveTransform(np.array([[principal]]), H).reshape(2)
            return {"center": np.array([nadir[0], nadir[1], camera_height]), "fitted": None,
                    "floor": None, "floor_sigma": None, "focal": None, "lens": False,
                    "R": None, "t": None}
        K = np.array([[focal, 0, principal[0]], [0, focal, principal[1]], [0, 0, 1]])
        dist = None
    obj = np.column_stack([floor, np.zeros(len(floor))])
    # the lens's own undistortion (iterated to convergence; solvePnP's is not, which a strong
    # lens's edges, where the floor markers are, would feel)
    ideal = px if dist is None else undistort(px, K, dist)
    ok, rvec, tvec = cv2.solvePnP(obj, ideal, K, None, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise InputError("cannot place the camera from the floor markers")
    R = cv2.Rodrigues(rvec)[0]
    fitted = (-R.T @ tvec).ravel()
    if fitted[2] <= 0:
        fitted = -fitted  # the mirror solution
    c = fitted.copy()
    if camera_height is not None:
        c[2] = camera_height
    return {"center": c, "fitted": fitted, "floor": floor_centre, "floor_sigma": floor_sigma,
            "focal": focal, "lens": lens is not None, "R": R, "t": tvec.ravel()}


def floor_alone_centre(H: np.ndarray, cov: np.ndarray, principal: Sequence[float]
                       ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The camera's centre the floor's perspective alone implies (the focal length that makes
    the free homography ``H`` a rotation: :func:`focal_from_homography`), and its uncertainty
    per axis (cm, sd) from the homography's covariance ``cov`` (its 8 parameters), through
    the 16 sigma points of ``cov``: the nearer square-on the view, the less the perspective
    tells. (None, None) when the view is too square-on to tell the focal length, at the fit
    or at any of its sigma points."""
    def centre(h: np.ndarray) -> np.ndarray | None:
        f = focal_from_homography(np.linalg.inv(h), principal)
        if f is None:
            return None
        return q.pose_from_homography(h, np.array([[f, 0, principal[0]],
                                                   [0, f, principal[1]], [0, 0, 1]]))

    c0 = centre(H)
    if c0 is None:
        return None, None
    p0 = (H / H[2, 2]).ravel()[:8]
    w, v = np.linalg.eigh((cov + cov.T) / 2)
    L = v * np.sqrt(np.maximum(w, 0.0) * len(p0))
    points = []
    for k in range(len(p0)):
        for sign in (1.0, -1.0):
            c = centre(np.append(p0 + sign * L[:, k], 1.0).reshape(3, 3))
            if c is None:
                return None, None
            points.append(c)
    return c0, np.sqrt(np.mean((np.array(points) - c0) ** 2, axis=0))
