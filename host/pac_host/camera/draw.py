"""The check image: a frame with the detected markers, the area's block grid as the
calibration puts it on the floor, and the robot's pose."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from pac_host.camera.calibrate import Calibration
from pac_host.camera.detect import Corners
from pac_host.camera.layout import AREA_X, AREA_Y, BLOCK_CM, heading_rotation


def check_image(frame: np.ndarray, calib: Calibration, corners: Corners,
                pose: Sequence[float] | None, height: float) -> np.ndarray:
    img = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if frame.ndim == 2 else frame.copy()

    iw, ih = calib.size

    def poly(a, b, z: float = 0.0) -> list[np.ndarray]:
        """The line a-b as drawn, in pieces where the lens model maps it into the image and
        back (not where it folds far outside the view)."""
        a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
        s = np.linspace(0, 1, max(60, int(np.hypot(*(b - a)) / 5)))[:, None]
        pts = a + s * (b - a)
        px = calib.from_floor(pts, z)
        ok = (np.hypot(*(calib.to_plane(px, z) - pts).T) < 0.5) & np.all(
            (px > [-iw, -ih]) & (px < [2 * iw, 2 * ih]), axis=1)
        cuts = np.split(np.arange(len(pts)), np.nonzero(np.diff(ok.astype(int)))[0] + 1)
        return [np.round(px[i]).astype(np.int32) for i in cuts if ok[i[0]] and len(i) > 1]

    _, _, wy0, wy1 = calib.layout.watched
    y0, y1 = max(AREA_Y[0], wy0), max(AREA_Y[0], wy1)  # the area's blocks watched
    lines = [p for x in np.arange(AREA_X[0], AREA_X[1] + 1, BLOCK_CM)
             for p in poly((x, y0), (x, y1))]
    lines += [p for y in np.arange(AREA_Y[0], y1 + 1, BLOCK_CM) if y >= y0
              for p in poly((AREA_X[0], y), (AREA_X[1], y))]
    cv2.polylines(img, lines, False, (0, 200, 255), 1, cv2.LINE_AA)
    if corners:
        ids = np.array(sorted(corners), dtype=np.int32).reshape(-1, 1)
        cv2.aruco.drawDetectedMarkers(
            img, [corners[i].reshape(1, 4, 2).astype(np.float32) for i in ids.ravel()], ids,
            (0, 255, 0))
    if pose is not None:
        x, y, h = pose
        tip = np.array([x, y]) + heading_rotation(h) @ [0.0, 20.0]
        a, b = calib.from_floor(np.array([[x, y], tip]), height)
        cv2.arrowedLine(img, tuple(np.round(a).astype(int)), tuple(np.round(b).astype(int)),
                        (255, 0, 255), 2, cv2.LINE_AA, tipLength=0.3)
        cv2.putText(img, f"({x:.1f}, {y:.1f}) cm, {h:.1f} deg", (8, img.shape[0] - 10),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 0, 255), 1, cv2.LINE_AA)
    return img
