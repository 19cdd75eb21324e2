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
    s = np.linspace(0, 1, 60)[:, None]

    def poly(a, b, h: float = 0.0) -> np.ndarray:
        pts = np.asarray(a) + s * (np.asarray(b) - np.asarray(a))
        return np.round(calib.from_floor(pts, h)).astype(np.int32)

    lines = [poly((x, AREA_Y[0]), (x, AREA_Y[1]))
             for x in np.arange(AREA_X[0], AREA_X[1] + 1, BLOCK_CM)]
    lines += [poly((AREA_X[0], y), (AREA_X[1], y))
              for y in np.arange(AREA_Y[0], AREA_Y[1] + 1, BLOCK_CM)]
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
