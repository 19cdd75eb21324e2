"""Markers in a frame (OpenCV's ArucoDetector with sub-pixel corners) and the robot's pose
from its marker's corners.

A small marker blurred by motion (~20 px across, 3 px of blur) is still found as a candidate
square, but its 3-px bits are too smeared for the detector's bit reading (a threshold per
cell). The one marker the caller looks for (``find``: the robot's) is then read from the
candidates the detector rejected by matched filtering (:func:`read_candidate`): the candidate
is rectified and compared with every marker of the dictionary in every orientation; it is the
sought marker only if that one matches clearly best.
"""

from __future__ import annotations

from collections.abc import Container
from dataclasses import dataclass

import cv2
import numpy as np

from pac_host.camera.layout import dictionary, square_corners

Corners = dict[int, np.ndarray]  # marker id -> its four corners in pixels (4, 2)


def make_detector(dict_name: str, refine: str = "subpix") -> cv2.aruco.ArucoDetector:
    """A detector tuned for small markers (~15-20 px across, 3 px of blur) with sub-pixel
    corners: thresholds over windows from 5 to 21 px, candidates down to a perimeter of 2 % of
    the image's longer side, a looser polygon fit (a blurred small square's corners are
    round)."""
    p = cv2.aruco.DetectorParameters()
    p.cornerRefinementMethod = {"subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
                                "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
                                "none": cv2.aruco.CORNER_REFINE_NONE}[refine]
    p.cornerRefinementWinSize = 3
    p.cornerRefinementMinAccuracy = 0.01
    p.cornerRefinementMaxIterations = 50
    p.minMarkerPerimeterRate = 0.02
    p.adaptiveThreshWinSizeMin = 5
    p.adaptiveThreshWinSizeMax = 21
    p.adaptiveThreshWinSizeStep = 8
    p.polygonalApproxAccuracyRate = 0.06
    p.perspectiveRemovePixelPerCell = 4
    p.perspectiveRemoveIgnoredMarginPerCell = 0.35  # read the bits' middles (~3 px per bit)
    return cv2.aruco.ArucoDetector(dictionary(dict_name), p)


def grey(frame: np.ndarray) -> np.ndarray:
    return frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)


def detect(detector: cv2.aruco.ArucoDetector, frame: np.ndarray,
           refine: Container[int] | None = None, find: int | None = None) -> Corners:
    """Every marker seen once: id -> corners (4, 2); a marker seen twice is dropped (it
    cannot be told which is real). The corners of the markers in ``refine`` (all if None) are
    refined by :func:`refine_corners`. Marker ``find``, if the detector did not read it, is
    looked for among the rejected candidates (:func:`read_candidate`)."""
    g = grey(frame)
    corners, ids, rejected = detector.detectMarkers(g)
    out: Corners = {}
    seen_twice = set()
    for c, i in zip(corners, [] if ids is None else ids.ravel(), strict=True):
        i = int(i)
        if i in out:
            seen_twice.add(i)
        out[i] = c.reshape(4, 2).astype(np.float64)
    for i in seen_twice:
        del out[i]
    out = {i: refine_corners(g, c) if refine is None or i in refine else c
           for i, c in out.items()}
    if find is not None and find not in out and find not in seen_twice:
        found = [c for c in (read_candidate(g, q.reshape(4, 2), detector.getDictionary(), find)
                             for q in rejected) if c is not None]
        if len(found) == 1:
            out[find] = found[0]
    return out


READ_PX = 4  # rectified pixels per bit cell when reading a candidate
READ_BLUR = 1.5  # the templates' blur (rectified px): a blurred marker matches a blurred one
MIN_MATCH = 0.55  # normalised correlation the sought marker must reach
MIN_LEAD = 0.04  # by how much it must beat every other marker of the dictionary
_TEMPLATES: dict[tuple[int, int], np.ndarray] = {}


def _templates(d: cv2.aruco.Dictionary) -> np.ndarray:
    """Every marker of the dictionary as a blurred, zero-mean, unit-norm image vector
    (n_ids, px * px)."""
    key = (d.markerSize, len(d.bytesList))
    if key not in _TEMPLATES:
        px = (d.markerSize + 2) * READ_PX
        out = []
        for i in range(len(d.bytesList)):
            t = cv2.aruco.generateImageMarker(d, i, px, borderBits=1).astype(np.float32)
            out.append(cv2.GaussianBlur(t, (0, 0), READ_BLUR).ravel())
        t = np.array(out)
        t -= t.mean(axis=1, keepdims=True)
        _TEMPLATES[key] = t / np.linalg.norm(t, axis=1, keepdims=True)
    return _TEMPLATES[key]


def read_candidate(gray: np.ndarray, quad: np.ndarray, d: cv2.aruco.Dictionary,
                   want: int) -> np.ndarray | None:
    """The corners (4, 2, marker order) of marker ``want`` if the candidate square ``quad``
    is it, else None. The quad (its corners refined) is rectified in each of its 8 corner
    orders (4 turns, both senses) and correlated with every marker of ``d``; it is ``want``
    when the best match is ``want``'s, at least :data:`MIN_MATCH`, and leads every other
    marker's best by :data:`MIN_LEAD`."""
    q = np.asarray(quad, dtype=np.float64)
    side = np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)
    if side.min() < 6 or side.max() > 3 * side.min():
        return None
    q = refine_corners(gray, q)
    px = (d.markerSize + 2) * READ_PX
    dst = np.array([[0, 0], [px, 0], [px, px], [0, px]], np.float32) - 0.5
    orders = [np.roll(q, -k, axis=0) for k in range(4)]
    orders += [o[::-1] for o in orders]
    patches = []
    for o in orders:
        H = cv2.getPerspectiveTransform(o.astype(np.float32), dst)
        patches.append(cv2.warpPerspective(gray, H, (px, px), flags=cv2.INTER_LINEAR,
                                           borderMode=cv2.BORDER_REPLICATE).ravel())
    v = np.array(patches, dtype=np.float32)
    v -= v.mean(axis=1, keepdims=True)
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    if np.any(norm < 1e-6):
        return None
    score = (v / norm) @ _templates(d).T  # (8 orders, ids)
    best = score.max(axis=0)
    others = np.delete(best, want)
    if best[want] < MIN_MATCH or best[want] - others.max() < MIN_LEAD:
        return None
    return orders[int(np.argmax(score[:, want]))]


def refine_corners(gray: np.ndarray, corners: np.ndarray, inside: float = 1.5,
                   outside: float = 3.0, samples: int = 10) -> np.ndarray:
    """Sub-pixel corners (4, 2) of a marker: each side's edge is found where the intensity
    crosses half-way from the black border to the white margin, on ``samples`` profiles across
    the side (away from the corners), a line is fitted to those edge points, and adjacent
    sides' lines are intersected. Unbiased for a blurred straight edge, unlike the contour's
    polygon (which lies up to a pixel inside a small marker); returns the input where a side
    gives no clean edge."""
    c = np.asarray(corners, dtype=np.float64)
    a, b = c, np.roll(c, -1, axis=0)  # side k runs from corner k to corner k + 1
    d = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    n = np.column_stack([d[:, 1], -d[:, 0]])
    n *= np.sign(np.sum(n * (a - c.mean(axis=0)), axis=1))[:, None]  # outward
    t = np.linspace(0.2, 0.8, samples)
    steps = np.arange(-inside, outside + 1e-9, 0.25)
    base = a[:, None] + t[None, :, None] * (b - a)[:, None]  # (4, samples, 2)
    pts = (base[:, :, None] + steps[None, None, :, None] * n[:, None, None]).astype(np.float32)
    prof = cv2.remap(gray, pts[..., 0].reshape(4 * samples, -1),
                     pts[..., 1].reshape(4 * samples, -1), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
    k = np.argmin(np.where(steps <= 0.5, prof, np.inf), axis=1)  # the border's darkest
    after = np.arange(len(steps))[None, :] > k[:, None]
    lo = prof[np.arange(len(k)), k]
    hi = np.where(after, prof, -np.inf).max(axis=1)
    level = (lo + hi) / 2
    above = after & (prof >= level[:, None])
    j = np.argmax(above, axis=1)
    if np.any(hi - lo < 20) or not np.all(above.any(axis=1)):
        return c
    rows = np.arange(len(j))
    f0, f1 = prof[rows, j - 1], prof[rows, j]
    s = steps[j - 1] + (level - f0) / (f1 - f0) * (steps[1] - steps[0])
    edge = base.reshape(-1, 2) + s[:, None] * np.repeat(n, samples, axis=0)
    edge = edge.reshape(4, samples, 2)
    m = edge.mean(axis=1)
    _, _, vt = np.linalg.svd(edge - m[:, None])
    u = vt[:, 0]  # each side's direction
    out = np.empty_like(c)
    for k in range(4):  # corner k joins side k - 1 and side k
        p1, d1, p2, d2 = m[k - 1], u[k - 1], m[k], u[k]
        A = np.column_stack([d1, -d2])
        if abs(np.linalg.det(A)) < 1e-6:
            return c
        out[k] = p1 + np.linalg.solve(A, p2 - p1)[0] * d1
    if np.abs(out - c).max() > 2.0:
        return c  # the lines went astray: keep the detector's corners
    return out


@dataclass(frozen=True)
class MarkerPose:
    """A marker's centre (cm) and compass heading (deg, in (-180, 180]) on its plane, and its
    size as seen relative to the nominal size (1 when the geometry is right)."""

    x: float
    y: float
    h: float
    scale: float


def fit_square(points: np.ndarray, size: float) -> MarkerPose:
    """The pose of a square of side ``size`` from its four corners on its plane (4, 2), in
    OpenCV's corner order: least-squares rotation (2-D Procrustes) about the centroid."""
    pts = np.asarray(points, dtype=np.float64)
    model = square_corners(size)
    c = pts.mean(axis=0)
    w = pts - c
    a = float(np.sum(w * model))
    b = float(np.sum(w[:, 0] * model[:, 1] - w[:, 1] * model[:, 0]))
    h = float(np.degrees(np.arctan2(b, a)))
    scale = float(np.sqrt((w ** 2).sum() / (model ** 2).sum()))
    return MarkerPose(float(c[0]), float(c[1]), h, scale)
