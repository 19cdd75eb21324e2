"""The pose update of DESIGN.md 2.2: the one definition of how a gait cycle moves the robot.

Pose (x, y, h): cm, cm, compass degrees (0 = +y, 90 = +x, clockwise positive), never wrapped.
A move (F, T, dH) is a displacement in the frame of the cycle's start pose, then a turn.

>>> import numpy as np
>>> integrate(np.array([45.0, 30.0, 90.0]), np.array([[12.1, -0.1, 0.0]]))[-1].round(6).tolist()
[57.1, 30.1, 90.0]
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pac_host.model.effects import Effect, step_moves


def integrate(
    start_pose: np.ndarray, body: np.ndarray, world: np.ndarray | None = None
) -> np.ndarray:
    """Poses (..., n + 1, 3) from a start pose (..., 3) and body-frame moves (..., n, 3).

    ``world`` (..., n, 2) is an optional world-frame drift added after each move.
    """
    start_pose = np.asarray(start_pose, dtype=np.float64)
    body = np.asarray(body, dtype=np.float64)
    n = body.shape[-2]
    lead = np.broadcast_shapes(start_pose.shape[:-1], body.shape[:-2])
    h = np.empty(lead + (n + 1,))
    h[..., 0] = start_pose[..., 2]
    np.cumsum(body[..., 2], axis=-1, out=h[..., 1:])
    h[..., 1:] += start_pose[..., 2:3]
    rad = np.radians(h[..., :-1])
    s, c = np.sin(rad), np.cos(rad)
    f, t = body[..., 0], body[..., 1]
    dx = f * s + t * c
    dy = f * c - t * s
    if world is not None:
        dx = dx + world[..., 0]
        dy = dy + world[..., 1]
    poses = np.empty(lead + (n + 1, 3))
    poses[..., 0, 0] = start_pose[..., 0]
    poses[..., 0, 1] = start_pose[..., 1]
    np.cumsum(dx, axis=-1, out=poses[..., 1:, 0])
    np.cumsum(dy, axis=-1, out=poses[..., 1:, 1])
    poses[..., 1:, 0] += start_pose[..., 0:1]
    poses[..., 1:, 1] += start_pose[..., 1:2]
    poses[..., 2] = h
    return poses


def rollout(
    rows: np.ndarray,
    start_pose: Sequence[float] | np.ndarray,
    gait_ids: Sequence[int] | np.ndarray,
    effects: Sequence[Effect] = (),
    n0: int = 0,
) -> np.ndarray:
    """Poses (n + 1, 3) of a run of gait cycles from a start pose, effects included."""
    body, world = step_moves(np.asarray(rows), np.asarray(gait_ids, dtype=np.int64), effects, n0)
    return integrate(np.asarray(start_pose, dtype=np.float64), body, world)
