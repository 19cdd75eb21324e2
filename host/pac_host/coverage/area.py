"""The coverage area (DESIGN.md 2.3) and block detection: the geometry every score counts on.

The area is x in [0, 180) cm, y >= 0, in 60 x 60 cm blocks (3 columns, rows unbounded upward);
a block is detected when the 12 cm body width, perpendicular to the heading at the body's mid
point, lies inside it. The robot starts at :data:`START_POSE` (x cm, y cm, heading degrees).

>>> detect_blocks(np.array([[90.0, 90.0, 0.0], [60.0, 30.0, 0.0]])).tolist()  # a border: -1
[4, -1]
"""

from __future__ import annotations

import numpy as np

START_POSE = (45.0, 30.0, 90.0)
BLOCK_CM = 60.0
COLUMNS = 3
AREA_WIDTH_CM = BLOCK_CM * COLUMNS
HALF_BODY_CM = 6.0


class _DetectScratch:
    """Scratch arrays of the body-width test for one (paths, poses) shape (the simulator's
    workspace extends them)."""

    def __init__(self, poses: tuple[int, int]) -> None:
        self.f = [np.empty(poses) for _ in range(6)]
        self.bad = np.empty(poses, dtype=bool)
        self.tmp = np.empty(poses, dtype=bool)
        self.blocks = np.empty(poses, dtype=np.int64)


def detect_blocks(poses: np.ndarray) -> np.ndarray:
    """Block detected at each pose (..., n) of paths (..., n, 3): row * 3 + column, or -1 where
    the body straddles a border or lies outside the area."""
    poses = np.asarray(poses, dtype=np.float64)
    rad = np.radians(poses[..., 2])
    flat = (a.reshape(-1, poses.shape[-2]) for a in
            (poses[..., 0], poses[..., 1], np.sin(rad), np.cos(rad)))
    x, y, s, c = flat
    return _detect(x, y, s, c, _DetectScratch(x.shape)).reshape(
        poses.shape[:-1]).copy()


def _detect(x: np.ndarray, y: np.ndarray, sin_h: np.ndarray, cos_h: np.ndarray,
            ws: _DetectScratch) -> np.ndarray:
    """The body-width test on (paths, poses) arrays, in the workspace's arrays (only the
    magnitudes of the heading's sine and cosine matter)."""
    hx, hy, lo, hi, col, row = ws.f
    bad, tmp = ws.bad, ws.tmp
    np.abs(cos_h, out=hx)
    hx *= HALF_BODY_CM
    np.abs(sin_h, out=hy)
    hy *= HALF_BODY_CM
    # x: both ends in the near end's column, and that column inside the area
    np.subtract(x, hx, out=lo)
    np.divide(lo, BLOCK_CM, out=col)
    np.floor(col, out=col)
    np.less(lo, 0, out=bad)  # the test runs as its negation, which saves a pass
    np.add(x, hx, out=hi)
    np.multiply(col, BLOCK_CM, out=lo)
    hi -= lo  # the far end's offset into the near end's column
    bad |= np.greater_equal(hi, BLOCK_CM, out=tmp)
    bad |= np.greater_equal(col, COLUMNS, out=tmp)
    # y: both ends in the near end's row, above y = 0
    np.subtract(y, hy, out=lo)
    np.divide(lo, BLOCK_CM, out=row)
    np.floor(row, out=row)
    bad |= np.less(lo, 0, out=tmp)
    np.add(y, hy, out=hi)
    np.multiply(row, BLOCK_CM, out=lo)
    hi -= lo
    bad |= np.greater_equal(hi, BLOCK_CM, out=tmp)
    row *= COLUMNS
    row += col
    np.copyto(row, -1.0, where=bad)
    np.copyto(ws.blocks, row, casting="unsafe")
    return ws.blocks
