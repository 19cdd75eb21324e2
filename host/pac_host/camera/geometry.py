"""The pinhole camera with lens distortion (OpenCV's model), placed in the floor frame."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Camera:
    """Intrinsics ``K`` (3, 3) and distortion ``dist`` (k1, k2, p1, p2, k3) of OpenCV, and the
    pose: ``R`` (3, 3) maps floor-frame vectors to the camera frame (x right in the image, y
    down, z along the view), ``center`` is where the lens is (cm, floor frame)."""

    size: tuple[int, int]  # width, height in pixels
    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    center: np.ndarray

    @staticmethod
    def looking_at(size: tuple[int, int], focal: float, center, target, right,
                   dist=(0.0, 0.0, 0.0, 0.0, 0.0)) -> Camera:
        """A camera at ``center`` looking at ``target``; ``right`` is the floor direction that
        should point to the image's right."""
        c, t, r = (np.asarray(v, dtype=np.float64) for v in (center, target, right))
        z = (t - c) / np.linalg.norm(t - c)
        x = r - (r @ z) * z
        x /= np.linalg.norm(x)
        R = np.stack([x, np.cross(z, x), z])
        K = np.array([[focal, 0, (size[0] - 1) / 2], [0, focal, (size[1] - 1) / 2], [0, 0, 1]])
        return Camera(size, K, np.asarray(dist, dtype=np.float64), R, c)

    @property
    def rvec(self) -> np.ndarray:
        return cv2.Rodrigues(self.R)[0]

    @property
    def tvec(self) -> np.ndarray:
        return -self.R @ self.center

    def project(self, points: np.ndarray) -> np.ndarray:
        """Floor-frame points (n, 3) to distorted pixels (n, 2)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 1, 3)
        px, _ = cv2.projectPoints(p, self.rvec, self.tvec, self.K, self.dist)
        return px.reshape(-1, 2)

    def rays(self, pixels: np.ndarray) -> np.ndarray:
        """Floor-frame directions (n, 3) of the rays through distorted pixels (n, 2)."""
        return pixel_rays(pixels, self.K, self.dist) @ self.R


def undistort(pixels: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> np.ndarray:
    """Distorted pixels (n, 2) to ideal pinhole pixels (n, 2) of the same ``K``."""
    pts = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
    if dist is None or not np.any(dist):
        return pts.reshape(-1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-9)
    return cv2.undistortPointsIter(pts, K, dist, None, K, crit).reshape(-1, 2)


def pixel_rays(pixels: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> np.ndarray:
    """Camera-frame directions (n, 3), z = 1, of distorted pixels (n, 2)."""
    ideal = undistort(pixels, K, dist)
    xy = (ideal - K[:2, 2]) / [K[0, 0], K[1, 1]]
    return np.column_stack([xy, np.ones(len(xy))])
