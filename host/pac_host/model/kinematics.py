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
    """Moves (..., 3) in the complex form :func:`scan_moves` works in (..., 2):
    the displacement ``T + i F`` and the heading rotation ``exp(-i dH)``."""
    body = np.asarray(body, dtype=np.float64)
    out = np.empty(body.shape[:-1] + (2,), dtype=np.complex128)
    out[..., 0] = body[..., 1] + 1j * body[..., 0]
    out[..., 1] = np.exp(-1j * np.radians(body[..., 2]))
    return out


def heading_rotation(h: np.ndarray | float) -> np.ndarray:
    """A compass heading (deg) as the unit complex number ``q = cos h - i sin h``."""
    return np.exp(-1j * np.radians(h))


def repeated_moves(moves: np.ndarray, max_reps: int) -> np.ndarray:
    """The move of r = 0..``max_reps`` repetitions of each of the complex moves (..., 2) that
    :func:`complex_moves` gives, as (..., max_reps + 1, 2): the displacement (in the frame of
    the first repetition's start) and the rotation. r repetitions of (d, rot) displace by
    ``d (1 + rot + ... + rot^(r-1))`` and turn by ``rot^r``, as :func:`scan_moves` walks them.

    >>> m = complex_moves(np.array([12.1, -0.1, 0.0]))
    >>> d, rot = repeated_moves(m, 2)[2]  # two straight gait cycles
    >>> complex(np.round(d, 6)), complex(np.round(rot, 6)).real
    ((-0.2+24.2j), 1.0)
    """
    moves = np.asarray(moves, dtype=np.complex128)
    powers = moves[..., 1, None] ** np.arange(max_reps + 1)
    out = np.empty(moves.shape[:-1] + (max_reps + 1, 2), dtype=np.complex128)
    out[..., 0, 0] = 0.0
    np.cumsum(powers[..., :-1], axis=-1, out=out[..., 1:, 0])
    out[..., 0] *= moves[..., 0, None]
    out[..., 1] = powers
    return out


def loop_moves(genes: np.ndarray, repeated: np.ndarray) -> np.ndarray:
    """The net move of one pass of each loop of genes (..., G, 2) of (gait id, repetitions),
    as (..., 2): displacement in the frame of the pass's start, and rotation, from the
    per-gait ``repeated`` moves (32, max_reps + 1, 2) of :func:`repeated_moves`. A loop that
    repeats within the budget walks its first pass again from where this move leaves it."""
    genes = np.asarray(genes, dtype=np.int64)
    steps = repeated[genes[..., 0], genes[..., 1]]
    out = np.zeros(genes.shape[:-2] + (2,), dtype=np.complex128)
    out[..., 1] = 1.0  # no move
    for j in range(genes.shape[-2]):
        out = compose_moves(out, steps[..., j, :])
    return out


def compose_moves(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The net move (..., 2) of move ``a`` then move ``b``, each (..., 2) a displacement in the
    frame of its start and a rotation (the form of :func:`repeated_moves`)."""
    a, b = np.broadcast_arrays(a, b)
    out = np.empty(a.shape, dtype=np.complex128)
    out[..., 0] = a[..., 0] + a[..., 1] * b[..., 0]
    out[..., 1] = a[..., 1] * b[..., 1]
    return out


def scan_moves(q: np.ndarray, p: np.ndarray, drift: np.ndarray | None = None) -> None:
    """The pose update over whole paths at once, in place, in complex form.

    On entry ``q`` (..., n + 2) holds ``[1, q_0, r_1 .. r_n]``: a one, the start heading as
    :func:`heading_rotation` and each move's rotation ``exp(-i dH)``; ``p`` (..., n + 1) holds
    ``[x_0 + i y_0, d_1 .. d_n]``: the start position and each move's displacement ``T + i F``.
    On return ``q[..., 1:]`` holds the headings ``q_0 .. q_n`` and ``p`` the positions.

    With q = cos h - i sin h, a move (F, T) in the frame of heading h displaces the robot by
    ``q * (T + i F)`` in the complex plane x + i y, and the heading advances as
    ``q' = q * exp(-i dH)``. So a population of paths costs one cumulative product, one
    product and one cumulative sum, with no per-step trigonometry; the leading one lines each
    move up with the heading it starts from. ``drift`` (broadcast to (..., n)) is a world-frame
    displacement added after each move.
    """
    np.multiply.accumulate(q, axis=-1, out=q)
    p *= q[..., :-1]
    if drift is not None:
        p[..., 1:] += drift
    np.add.accumulate(p, axis=-1, out=p)


def integrate_path(
    start_pose: np.ndarray,
    body: np.ndarray,
    world: np.ndarray | None = None,
    headings: bool = True,
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> Path:
    """Integrate body-frame moves (..., n, 3) from a start pose (..., 3) into a :class:`Path`.

    ``world`` (..., n, 2) is an optional world-frame drift added after each move. ``out`` may
    give the two complex arrays :func:`scan_moves` works in, (..., n + 2) and (..., n + 1), so
    a hot loop need not allocate them each call.
    """
    start_pose = np.asarray(start_pose, dtype=np.float64)
    body = np.asarray(body, dtype=np.float64)
    cmoves = complex_moves(body)
    n = cmoves.shape[-2]
    lead = np.broadcast_shapes(start_pose.shape[:-1], cmoves.shape[:-2])
    q, p = out if out is not None else (np.empty(lead + (n + 2,), dtype=np.complex128),
                                        np.empty(lead + (n + 1,), dtype=np.complex128))
    q[..., 0] = 1.0
    q[..., 1] = heading_rotation(start_pose[..., 2])
    q[..., 2:] = cmoves[..., 1]
    p[..., 0] = start_pose[..., 0] + 1j * start_pose[..., 1]
    p[..., 1:] = cmoves[..., 0]
    scan_moves(q, p, None if world is None else world[..., 0] + 1j * world[..., 1])
    h = accumulate_headings(start_pose[..., 2], body[..., 2], lead) if headings else None
    return Path(p.real, p.imag, h, -q[..., 1:].imag, q[..., 1:].real)


def accumulate_headings(h0: np.ndarray | float, dh: np.ndarray,
                        lead: tuple[int, ...] | None = None) -> np.ndarray:
    """Unwrapped headings (..., n + 1) from a start heading and heading changes (..., n)."""
    h0 = np.asarray(h0, dtype=np.float64)
    lead = dh.shape[:-1] if lead is None else lead
    h = np.empty(lead + (dh.shape[-1] + 1,))
    h[..., 0] = h0
    np.cumsum(dh, axis=-1, out=h[..., 1:])
    h[..., 1:] += h0[..., None]
    return h


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
