"""The coverage simulator (DESIGN.md 2.3): the hot loop of everything.

Runs whole populations of turn cycles on one or many gait tables at once with numpy, and scores
each path: blocks covered, blocks covered exactly once, the coverage fitness ``3 R + c`` and
repeat visits.

The area is x in [0, 180) cm, y >= 0, in 60 x 60 cm blocks (3 columns, rows unbounded upward);
a block is detected when the 12 cm body width, perpendicular to the heading at the body's mid
point, lies inside it. Detection is checked at the start pose and after every gait cycle.

>>> from pac_host.model import measured_table
>>> cov = simulate(measured_table().rows, parse_turn_cycle("12:63"))  # straight on, eastward
>>> cov.row(0)  # row 0 swept once, then the robot leaves the area
{'blocks_covered': 3, 'blocks_covered_once': 3, 'fitness': 3, 'repeat_visits': 0}
"""

from __future__ import annotations

import re
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.errors import InputError
from pac_host.model.effects import (
    Effect,
    effective_rows,
    gather_rows,
    has_sequence_effects,
    step_moves,
    world_drift,
)
from pac_host.model.kinematics import complex_moves, integrate_path

START_POSE = (45.0, 30.0, 90.0)
BLOCK_CM = 60.0
COLUMNS = 3
AREA_WIDTH_CM = BLOCK_CM * COLUMNS
HALF_BODY_CM = 6.0
MAX_GENES = 9
MAX_GAIT_ID = 31
MAX_REPS = 63
DEFAULT_BUDGET = 200


@dataclass(frozen=True)
class Coverage:
    """Coverage figures of a batch of paths (all arrays share the batch shape)."""

    blocks_covered: np.ndarray
    blocks_covered_once: np.ndarray
    fitness: np.ndarray
    repeat_visits: np.ndarray
    poses: np.ndarray | None = None
    blocks: np.ndarray | None = None  # detected block per pose, -1 for none

    def score(self) -> np.ndarray:
        """One sortable number per path: higher fitness first, then fewer repeat visits."""
        return coverage_score(self.fitness, self.repeat_visits)

    def row(self, index: int | tuple = 0) -> dict:
        """The figures of one path as a dict (any index for a single path)."""

        def get(a: np.ndarray) -> int:
            return int(a) if np.ndim(a) == 0 else int(a[index])

        return {
            "blocks_covered": get(self.blocks_covered),
            "blocks_covered_once": get(self.blocks_covered_once),
            "fitness": get(self.fitness),
            "repeat_visits": get(self.repeat_visits),
        }


def coverage_score(fitness: np.ndarray, repeat_visits: np.ndarray) -> np.ndarray:
    """Lexicographic (fitness, -repeat visits) as one integer per path."""
    return np.asarray(fitness, dtype=np.int64) * 4096 - np.asarray(repeat_visits, dtype=np.int64)


def fitness_of_score(score: np.ndarray | int) -> np.ndarray | int:
    """The coverage fitness inside a :func:`coverage_score` (repeat visits are < 4096)."""
    return -(-np.asarray(score) // 4096)


def parse_turn_cycle(text: str) -> np.ndarray:
    """Parse ``"12:14,3:10"`` (gait id:repetitions, up to 9 genes) into a (9, 2) gene array.

    Unused gene slots get 0 repetitions, which the robot skips.
    """
    items = [s.strip() for s in text.split(",") if s.strip()]
    if not items:
        raise InputError("turn cycle is empty: expected 'id:reps,...' e.g. '12:14,3:10'")
    if len(items) > MAX_GENES:
        raise InputError(f"turn cycle has {len(items)} genes; at most {MAX_GENES}")
    genes = np.zeros((MAX_GENES, 2), dtype=np.int64)
    for k, item in enumerate(items):
        m = re.fullmatch(r"(-?\d+)\s*:\s*(-?\d+)", item)
        if not m:
            raise InputError(f"turn cycle gene {k + 1} {item!r}: expected 'id:reps' e.g. '12:14'")
        gid, reps = int(m.group(1)), int(m.group(2))
        if not 0 <= gid <= MAX_GAIT_ID:
            raise InputError(f"turn cycle gene {k + 1}: gait cycle id {gid} outside 0..31")
        if not 0 <= reps <= MAX_REPS:
            raise InputError(f"turn cycle gene {k + 1}: repetitions {reps} outside 0..63")
        genes[k] = gid, reps
    return genes


def format_turn_cycle(genes: np.ndarray) -> str:
    """The inverse of :func:`parse_turn_cycle`, leaving out skipped genes."""
    return ",".join(f"{int(g)}:{int(r)}" for g, r in np.asarray(genes) if r > 0)


def check_budget(budget: int) -> int:
    if not isinstance(budget, int | np.integer) or budget < 0:
        raise InputError(f"budget must be a non-negative number of gait cycles, got {budget}")
    return int(budget)


def expand(genes: np.ndarray, budget: int) -> tuple[np.ndarray, np.ndarray]:
    """Gait ids executed by each looped turn cycle: genes (P, 9, 2) -> ids (P, budget).

    Also returns a (P,) mask of turn cycles with no repetitions at all, which stand still.
    """
    genes = np.asarray(genes)
    ids, reps = genes[..., 0], genes[..., 1]
    loop_len = reps.sum(axis=-1)
    still = loop_len == 0
    flat = np.repeat(ids.ravel(), reps.ravel())
    if flat.size == 0:
        flat = np.zeros(1, dtype=ids.dtype)
    offsets = np.cumsum(loop_len) - loop_len
    # position in the loop, t mod L, via a floor (exact: t / L is never within 1e-9 of an
    # integer unless it is one) because integer modulo is the slowest numpy operation here
    t = np.arange(budget, dtype=np.float64)[None, :]
    length = np.maximum(loop_len, 1).astype(np.float64)[:, None]
    idx = t - length * np.floor(t * (1.0 / length) + 1e-9)
    idx += offsets[:, None]
    out = np.take(flat, idx.astype(np.int64), mode="clip")
    return out, still


class _Workspace:
    """Scratch arrays for one (paths, poses) shape, reused chunk after chunk: allocating them
    afresh costs more in page faults than the arithmetic done in them."""

    def __init__(self, shape: tuple[int, int]) -> None:
        self.q = np.empty(shape, dtype=np.complex128)
        self.p = np.empty(shape, dtype=np.complex128)
        self.f = [np.empty(shape) for _ in range(6)]
        self.ok = np.empty(shape, dtype=bool)
        self.tmp = np.empty(shape, dtype=bool)
        self.blocks = np.empty(shape, dtype=np.int64)
        self.prev = np.empty(shape, dtype=np.int64)


_local = threading.local()


def _workspace(shape: tuple[int, int]) -> _Workspace:
    cache = _local.__dict__.setdefault("cache", {})
    ws = cache.get(shape)
    if ws is None:
        if len(cache) >= 8:
            cache.clear()
        ws = cache[shape] = _Workspace(shape)
    return ws


def detect_blocks(poses: np.ndarray) -> np.ndarray:
    """Block detected at each pose (..., n) of paths (..., n, 3): row * 3 + column, or -1 where
    the body straddles a border or lies outside the area."""
    poses = np.asarray(poses, dtype=np.float64)
    rad = np.radians(poses[..., 2])
    flat = (a.reshape(-1, poses.shape[-2]) for a in
            (poses[..., 0], poses[..., 1], np.sin(rad), np.cos(rad)))
    x, y, s, c = flat
    return _detect(x, y, s, c, _Workspace(x.shape)).reshape(poses.shape[:-1]).copy()


def _detect(x: np.ndarray, y: np.ndarray, sin_h: np.ndarray, cos_h: np.ndarray,
            ws: _Workspace) -> np.ndarray:
    """The body-width test on (paths, poses) arrays, in the workspace's arrays."""
    hx, hy, lo, hi, col, row = ws.f
    ok, tmp = ws.ok, ws.tmp
    np.abs(cos_h, out=hx)
    hx *= HALF_BODY_CM
    np.abs(sin_h, out=hy)
    hy *= HALF_BODY_CM
    # x: both ends in the near end's column, and that column inside the area
    np.subtract(x, hx, out=lo)
    np.divide(lo, BLOCK_CM, out=col)
    np.floor(col, out=col)
    np.greater_equal(lo, 0, out=ok)
    np.add(x, hx, out=hi)
    np.multiply(col, BLOCK_CM, out=lo)
    hi -= lo  # the far end's offset into the near end's column
    ok &= np.less(hi, BLOCK_CM, out=tmp)
    ok &= np.less(col, COLUMNS, out=tmp)
    # y: both ends in the near end's row, above y = 0
    np.subtract(y, hy, out=lo)
    np.divide(lo, BLOCK_CM, out=row)
    np.floor(row, out=row)
    ok &= np.greater_equal(lo, 0, out=tmp)
    np.add(y, hy, out=hi)
    np.multiply(row, BLOCK_CM, out=lo)
    hi -= lo
    ok &= np.less(hi, BLOCK_CM, out=tmp)
    row *= COLUMNS
    row += col
    np.copyto(row, -1.0, where=np.logical_not(ok, out=tmp))
    np.copyto(ws.blocks, row, casting="unsafe")
    return ws.blocks


def figures_from_blocks(blocks: np.ndarray, prev: np.ndarray | None = None
                        ) -> tuple[np.ndarray, ...]:
    """(covered, covered once, fitness, repeat visits) from detected blocks (..., n)."""
    lead = blocks.shape[:-1]
    b = blocks.reshape(-1, blocks.shape[-1])
    n_paths = b.shape[0]
    if prev is None:
        prev = np.empty_like(b)
    prev[:, 0] = -1
    prev[:, 1:] = b[:, :-1]
    start = prev != b  # a visit starts where detection enters a block
    start &= b >= 0
    n_rows = int(b.max(initial=-1)) // COLUMNS + 2
    n_blocks = n_rows * COLUMNS
    where = np.flatnonzero(start)  # the few visit starts, not every pose
    key = where // b.shape[1] * n_blocks + b.ravel()[where]
    visits = np.bincount(key, minlength=n_paths * n_blocks)
    visits = visits.reshape(n_paths, n_rows, COLUMNS)
    covered = visits > 0
    blocks_covered = covered.sum(axis=(1, 2))
    once = (visits == 1).sum(axis=(1, 2))
    repeat = visits.sum(axis=(1, 2)) - blocks_covered
    per_row = covered.sum(axis=2)
    full = per_row == COLUMNS  # the top row is always empty, so argmin finds a gap
    r = np.argmin(full, axis=1)
    c = per_row[np.arange(n_paths), r]
    fitness = COLUMNS * r + c
    return tuple(a.reshape(lead) for a in (blocks_covered, once, fitness, repeat))


def coverage_of_poses(poses: np.ndarray, keep: bool = False) -> Coverage:
    """Coverage figures of given paths (..., n + 1, 3), e.g. a path observed on the robot."""
    poses = np.asarray(poses, dtype=np.float64)
    blocks = detect_blocks(poses)
    covered, once, fitness, repeat = figures_from_blocks(blocks)
    return Coverage(covered, once, fitness, repeat, poses if keep else None,
                    blocks if keep else None)


# Paths per inner batch: keeps every temporary in cache and off the page-fault path.
CHUNK_PATHS = 64


def simulate(
    rows: np.ndarray,
    genes: np.ndarray,
    budget: int = DEFAULT_BUDGET,
    effects: Sequence[Effect] = (),
    start_pose: Sequence[float] = START_POSE,
    keep_paths: bool = False,
) -> Coverage:
    """Run turn cycles on gait tables and score the paths.

    ``rows`` is one table (32, 3) or M tables (M, 32, 3); ``genes`` is one turn cycle (9, 2) or
    P of them (P, 9, 2). The result's arrays have shape (P,) for one table, (M, P) for M.
    """
    budget = check_budget(budget)
    rows = np.asarray(rows, dtype=np.float64)
    genes = np.asarray(genes, dtype=np.int64)
    if genes.ndim == 2:
        genes = genes[None]
    n_tables = 1 if rows.ndim == 2 else rows.shape[0]
    n_genes = genes.shape[0]
    n_paths = n_tables * n_genes
    start = np.asarray(start_pose, dtype=np.float64)
    effects = tuple(effects)
    figures = np.empty((4, n_paths), dtype=np.int64)
    poses = np.empty((n_paths, budget + 1, 3)) if keep_paths else None
    blocks = np.empty((n_paths, budget + 1), dtype=np.int64) if keep_paths else None
    for lo in range(0, n_paths, CHUNK_PATHS):
        k = np.arange(lo, min(lo + CHUNK_PATHS, n_paths))
        rows_k = rows if rows.ndim == 2 else rows[k // n_genes]
        path, blocks_k = _run_chunk(rows_k, genes[k % n_genes], budget, effects, start, keep_paths)
        figures[:, k] = figures_from_blocks(blocks_k, _workspace(blocks_k.shape).prev)
        if keep_paths:
            poses[k] = path.poses()
            blocks[k] = blocks_k
    shape = (n_genes,) if rows.ndim == 2 else (n_tables, n_genes)
    covered, once, fitness, repeat = (f.reshape(shape) for f in figures)
    if keep_paths:
        poses = poses.reshape(shape + poses.shape[1:])
        blocks = blocks.reshape(shape + blocks.shape[1:])
    return Coverage(covered, once, fitness, repeat, poses, blocks)


def _run_chunk(rows, genes, budget, effects, start, headings):
    """Paths and detected blocks of a small batch: one table (32, 3) or one per turn cycle."""
    ids, still = expand(genes, budget)
    if has_sequence_effects(effects):
        body, world = step_moves(rows, ids, effects)
        cmoves = complex_moves(body)
    else:  # moves depend on the gait id alone: look them up from 32 precomputed rows
        table = effective_rows(rows, effects)
        body = gather_rows(table, ids) if headings else None
        cmoves = gather_rows(complex_moves(table), ids)
        drift = world_drift(effects)
        world = None if drift is None else np.broadcast_to(drift, ids.shape + (2,))
    if still.any():
        cmoves[still] = (0.0, 1.0)
        if body is not None:
            body = body.copy()
            body[still] = 0.0
        if world is not None:
            world = np.array(world)
            world[still] = 0.0
    ws = _workspace(ids.shape[:-1] + (budget + 1,))
    path = integrate_path(start, body, world, cmoves, headings, (ws.q, ws.p))
    return path, _detect(path.x, path.y, path.sin_h, path.cos_h, ws)
