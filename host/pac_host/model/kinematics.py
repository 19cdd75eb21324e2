"""The pose update of DESIGN.md 2.2: the one definition of how a gait cycle moves the robot.

Pose (x, y, h): cm, cm, compass degrees (0 = +y, 90 = +x, clockwise positive), never wrapped.
A move (F, T, dH) is a displacement in the frame of the cycle's start pose, then a turn.

>>> import numpy as np
>>> integrate(np.array([45.0, 30.0, 90.0]), np.array([[12.1, -0.1, 0.0]]))[-1].round(6).tolist()
[57.1, 30.1, 90.0]
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from pac_host.model.effects import Effect, step_moves


class Path(NamedTuple):
    """A batch of paths as separate arrays (..., n + 1): the fast internal form.

    ``h`` is None when the caller did not ask for headings (the coverage test needs only their
    sine and cosine).
    """

    x: np.ndarray
    y: np.ndarray
    h: np.ndarray | None
    sin_h: np.ndarray
    cos_h: np.ndarray

    def poses(self) -> np.ndarray:
        return np.stack((self.x, self.y, self.h), axis=-1)


def complex_moves(body: np.ndarray) -> np.ndarray:
    """Moves (..., 3) in the complex form :func:`integrate_path` works in (..., 2):
    the displacement ``T + i F`` and the heading rotation ``exp(-i dH)``."""
    body = np.asarray(body, dtype=np.float64)
    out = np.empty(body.shape[:-1] + (2,), dtype=np.complex128)
    out[..., 0] = body[..., 1] + 1j * body[..., 0]
    out[..., 1] = np.exp(-1j * np.radians(body[..., 2]))
    return out


def integrate_path(
    start_pose: np.ndarray,
    body: np.ndarray | None,
    world: np.ndarray | None = None,
    cmoves: np.ndarray | None = None,
    headings: bool = True,
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> Path:
    """Integrate body-frame moves (..., n, 3) from a start pose (..., 3) into a :class:`Path`.

    With q = cos h - i sin h, a move (F, T) in the frame of heading h displaces the robot by
    ``q * (T + i F)`` in the complex plane x + i y, and the heading advances as
    ``q' = q * exp(-i dH)``. So a population of paths costs one cumulative product and one
    cumulative sum, with no per-step trigonometry. ``cmoves`` may supply the moves already in
    that form (see :func:`complex_moves`), e.g. looked up per gait id from a table of 32;
    ``body`` then only needs to provide dH for the headings. ``world`` (..., n, 2) is a
    world-frame drift added after each move. ``out`` may give two complex arrays (..., n + 1)
    to work in (heading and position), so a hot loop need not allocate them each call.
    """
    start_pose = np.asarray(start_pose, dtype=np.float64)
    if cmoves is None:
        cmoves = complex_moves(body)
    n = cmoves.shape[-2]
    lead = np.broadcast_shapes(start_pose.shape[:-1], cmoves.shape[:-2])
    # the start pose goes in as element 0, so one in-place scan carries it along
    q, p = out if out is not None else (np.empty(lead + (n + 1,), dtype=np.complex128),
                                        np.empty(lead + (n + 1,), dtype=np.complex128))
    q[..., 0] = np.exp(-1j * np.radians(start_pose[..., 2]))
    q[..., 1:] = cmoves[..., 1]
    np.multiply.accumulate(q, axis=-1, out=q)
    p[..., 0] = start_pose[..., 0] + 1j * start_pose[..., 1]
    np.multiply(cmoves[..., 0], q[..., :-1], out=p[..., 1:])
    if world is not None:
        p[..., 1:] += world[..., 0] + 1j * world[..., 1]
    np.add.accumulate(p, axis=-1, out=p)
    h = None
    if headings:
        body = np.asarray(body, dtype=np.float64)
        h = np.empty(lead + (n + 1,))
        h[..., 0] = start_pose[..., 2]
        np.cumsum(body[..., 2], axis=-1, out=h[..., 1:])
        h[..., 1:] += start_pose[..., 2:3]
    return Path(p.real, p.imag, h, -q.imag, q.real)


def integrate(
    start_pose: np.ndarray, body: np.ndarray, world: np.ndarray | None = None
) -> np.ndarray:
    """Poses (..., n + 1, 3) from a start pose (..., 3) and body-frame moves (..., n, 3).

    ``world`` (..., n, 2) is an optional world-frame drift added after each move.
    """
    return integrate_path(start_pose, body, world).poses()


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


def to_body_frame(dx: np.ndarray, dy: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A world-frame displacement (dx, dy) in the frame of heading ``h`` (deg): (F, T).

    The inverse of the displacement part of the pose update: F = dx sin h + dy cos h,
    T = dx cos h - dy sin h.
    """
    rad = np.radians(h)
    s, c = np.sin(rad), np.cos(rad)
    return dx * s + dy * c, dx * c - dy * s


def moves_between(poses: np.ndarray) -> np.ndarray:
    """Body-frame moves (..., n, 3) that take each pose of (..., n + 1, 3) to the next one.

    The inverse of :func:`integrate` without world drift: each move is expressed in the frame
    of the pose before it, so ``integrate(poses[0], moves_between(poses))`` gives ``poses``
    back. Used to turn observed poses into observed gait-cycle moves.
    """
    poses = np.asarray(poses, dtype=np.float64)
    d = np.diff(poses, axis=-2)
    f, t = to_body_frame(d[..., 0], d[..., 1], poses[..., :-1, 2])
    return np.stack((f, t, d[..., 2]), axis=-1)
