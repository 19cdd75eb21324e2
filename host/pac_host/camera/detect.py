"""Markers in a frame (OpenCV's ArucoDetector with sub-pixel corners) and the robot's pose
from its marker's corners."""

from __future__ import annotations

from collections.abc import Container
from dataclasses import dataclass

import cv2
import numpy as np

from pac_host.camera.layout import dictionary, square_corners

Corners = dict[int, np.ndarray]  # marker id -> its four corners in pixels (4, 2)


def make_detector(dict_name: str, refine: str = "subpix") -> cv2.aruco.ArucoDetector:
    """A detector tuned for small markers (~20 px) with sub-pixel corners."""
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
    p.perspectiveRemovePixelPerCell = 4
    p.perspectiveRemoveIgnoredMarginPerCell = 0.35  # read the bits' middles (~3 px per bit)
    return cv2.aruco.ArucoDetector(dictionary(dict_name), p)


def grey(frame: np.ndarray) -> np.ndarray:
    return frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)


def detect(detector: cv2.aruco.ArucoDetector, frame: np.ndarray,
           refine: Container[int] | None = None) -> Corners:
    """Every marker seen once: id -> corners (4, 2); a marker seen twice is dropped (it
    cannot be told which is real). The corners of the markers in ``refine`` (all if None) are
    refined by :func:`refine_corners`."""
    g = grey(frame)
    corners, ids, _ = detector.detectMarkers(g)
    out: Corners = {}
    seen_twice = set()
    for c, i in zip(corners, [] if ids is None else ids.ravel(), strict=True):
        i = int(i)
        if i in out:
            seen_twice.add(i)
        out[i] = c.reshape(4, 2).astype(np.float64)
    for i in seen_twice:
        del out[i]
    return {i: refine_corners(g, c) if refine is None or i in refine else c
            for i, c in out.items()}


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
