"""The coverage simulator compiled with numba: one path at a time, no temporaries.

The same arithmetic as the numpy simulator in :mod:`pac_host.coverage`, operation for operation
(the heading as a running complex product, each move rotated by the heading it starts from, the
positions as a running sum, the body-width test on each pose), so both give the same figures
value for value; the numpy simulator stays the reference the tests compare this kernel with.
It covers what the search needs: scores of turn cycles on one or many tables whose effects
depend on the gait id alone (plus a world drift), the built-in ``transition`` effect, whose
blended moves depend on the gait id and the one before it, and the built-in ``battery_sag``,
whose moves depend on the gait id and the step's index in the run. The caller tabulates the
moves, per gait id or pair of gait ids and (with ``battery_sag``) per step, with the same
conversion the numpy simulator uses, and the kernel looks them up. Kept paths and user-defined
sequence effects run in numpy.

Set ``PAC_KERNEL=numpy`` in the environment to run everything in numpy.
"""

from __future__ import annotations

import importlib.util
import os

import numpy as np

# numba is a dependency; the numpy simulator stands in where it is missing. It is imported on
# the first evaluation, not with the package: commands that simulate nothing start faster.
AVAILABLE = (importlib.util.find_spec("numba") is not None
             and os.environ.get("PAC_KERNEL", "numba") != "numpy")
_compiled = None

_BLOCK = 60.0
_COLUMNS = 3
_HALF_BODY = 6.0


def _block(x: float, y: float, c: float, s: float) -> int:
    """Block detected at position (x, y) with heading cosine ``c`` and sine ``s``: as
    ``coverage.area._detect``, one pose at a time, with the same floor of the same quotient. The
    tests are combined without branches: whether a body straddles a border varies from pose
    to pose, and a mispredicted early return cost more than the arithmetic (measured: the
    kernel 13% faster on a search's batches, the same figures)."""
    hx = abs(c) * _HALF_BODY
    hy = abs(s) * _HALF_BODY
    lox = x - hx
    loy = y - hy
    col = np.floor(lox / _BLOCK)
    row = np.floor(loy / _BLOCK)
    bad = ((lox < 0) | (loy < 0) | (col >= _COLUMNS)
           | ((x + hx) - col * _BLOCK >= _BLOCK) | ((y + hy) - row * _BLOCK >= _BLOCK))
    return -1 if bad else int(row * _COLUMNS + col)


def _figures(blocks: np.ndarray, n: int, top: int, visits: np.ndarray, first: np.ndarray,
             out: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(covered, covered once, fitness, repeat visits, reached at) of one path's detected
    blocks (``top`` the highest) into ``out[:, k]``: as ``coverage.scores.figures_from_blocks``.
    ``visits`` and ``first`` (the step each block was first detected at) are scratch buffers,
    grown when a path reaches further; returns them. One pass over the steps, then one over
    the blocks: the figures cost no more than the blocks a path reaches."""
    n_rows = top // _COLUMNS + 2
    if visits.shape[0] < n_rows * _COLUMNS:
        visits = np.zeros(2 * n_rows * _COLUMNS, dtype=np.int64)
        first = np.zeros(2 * n_rows * _COLUMNS, dtype=np.int64)
    else:
        visits[: n_rows * _COLUMNS] = 0
    prev = -1
    for t in range(n):
        b = blocks[t]
        if b >= 0 and b != prev:
            if visits[b] == 0:
                first[b] = t
            visits[b] += 1
        prev = b
    covered = once = total = 0
    fitness = -1
    for r in range(n_rows):
        in_row = 0
        for c in range(_COLUMNS):
            v = visits[r * _COLUMNS + c]
            total += v
            if v > 0:
                covered += 1
                in_row += 1
            if v == 1:
                once += 1
        if fitness < 0 and in_row < _COLUMNS:
            fitness = _COLUMNS * r + in_row
    out[0, k] = covered
    out[1, k] = once
    out[2, k] = fitness
    out[3, k] = total - covered
    # reached at: the pose at which the last of the blocks the fitness counts (every block
    # of the full rows, the covered ones of the first row that is not) was first detected
    reached = 0
    end = (fitness // _COLUMNS + 1) * _COLUMNS
    for b in range(end):
        if visits[b] > 0 and first[b] > reached:
            reached = first[b]
    out[4, k] = reached
    return visits, first


def _shared_steps(a: np.ndarray, b: np.ndarray, budget: int) -> int:
    """Gait cycles at the start that turn cycles ``a`` and ``b`` (G, 2) walk alike: their equal
    genes, then the shorter run of the first gene that differs, if its id is the same in both
    (in the loop's first pass)."""
    steps = 0
    for j in range(a.shape[0]):
        if a[j, 0] == b[j, 0] and a[j, 1] == b[j, 1]:
            steps += a[j, 1]
            if steps >= budget:
                return budget
            continue
        if a[j, 0] == b[j, 0]:
            steps += min(a[j, 1], b[j, 1])
        return min(steps, budget)
    return min(steps, budget)


def _transition_pairs(genes: np.ndarray, out: np.ndarray) -> None:
    """Mark in ``out`` (32 * 32,) at ``prev * 32 + gait`` each change of gait id that turn
    cycles ``genes`` (P, G, 2) can make: from each gene with repetitions to the next one, the
    last to the first, skipping genes without repetitions."""
    for k in range(genes.shape[0]):
        g = genes[k]
        first = prev = -1
        for j in range(g.shape[0]):
            if g[j, 1] == 0:
                continue
            if first < 0:
                first = g[j, 0]
            elif g[j, 0] != prev:
                out[prev * 32 + g[j, 0]] = True
            prev = g[j, 0]
        if first >= 0 and first != prev:
            out[prev * 32 + first] = True


def _score_paths(genes: np.ndarray, n_tables: int, rot: np.ndarray, disp: np.ndarray,
                 n_steps: int, q0: complex, p0: complex, drift: complex, budget: int,
                 slots: np.ndarray, n_slots: int, blend_rot: np.ndarray, blend_disp: np.ndarray
                 ) -> np.ndarray:
    """Figures (5, n_tables * P) of turn cycles ``genes`` (P, G, 2) on tables whose moves are
    ``rot`` and ``disp`` (n_tables * 32 * n_steps,): path k runs genes k % P on table k // P.
    Gait id g of table m moves at step t (1..budget) by entry ``(m * 32 + g) * n_steps + i``,
    i = min(t - 1, n_steps - 1): with ``n_steps`` 1 the move depends on the gait id alone, with
    more on the step too (battery sag), the last entry standing for every later step.

    With ``n_slots`` > 0, a gait cycle whose gait id differs from the one just before it in the
    path (not the path's first) moves by ``blend_rot`` and ``blend_disp``
    (n_tables * n_slots * n_steps,) instead, at slot ``slots[prev * 32 + gait]`` of its table
    (indexed as the moves are): a transition's blended move.

    Each path starts where it parts from the path before it on the same table: the gait
    cycles they walk alike are not walked again (a search's batch changes one gene and keeps
    those before it, and lists a gene's repetitions in order, so most of each path is shared).
    The pose and loop position after every gait cycle of the last path are kept for this (the
    gait id walked last, which a transition needs, is that of the gene there)."""
    n_genes = genes.shape[0]
    n_paths = n_tables * n_genes
    blend = n_slots > 0
    out = np.empty((5, n_paths), dtype=np.int64)
    blocks = np.empty(budget + 1, dtype=np.int64)
    qs = np.empty(budget + 1, dtype=np.complex128)
    ps = np.empty(budget + 1, dtype=np.complex128)
    js = np.empty(budget + 1, dtype=np.int64)
    used = np.empty(budget + 1, dtype=np.int64)  # repetitions of gene js[t] walked by t
    tops = np.empty(budget + 1, dtype=np.int64)  # the highest block detected by t
    visits = np.zeros(64, dtype=np.int64)
    first = np.zeros(64, dtype=np.int64)
    blocks[0] = _block(p0.real, p0.imag, q0.real, q0.imag)
    qs[0] = q0
    ps[0] = p0
    tops[0] = blocks[0]
    for k in range(n_paths):
        g = genes[k % n_genes]
        base = (k // n_genes) * 32
        blend_base = (k // n_genes) * n_slots
        loop = 0
        for j in range(g.shape[0]):
            loop += g[j, 1]
        s = 0
        if k % n_genes != 0:
            s = _shared_steps(g, genes[k % n_genes - 1], budget)
        q = qs[s]
        p = ps[s]
        top = tops[s]
        # a later path shares at most this path's first pass of the loop: the state after
        # each gait cycle is kept that far
        keep = min(loop, budget)
        prev = -1  # the gait id walked last: none at the start
        if s == 0:
            j = 0
            left = g[0, 1]
        else:
            j = js[s]
            left = g[j, 1] - used[s]
            prev = g[j, 0]
        for t in range(s + 1, budget + 1):
            if loop == 0:  # a turn cycle without repetitions stands still
                r = 1.0 + 0.0j
                d = 0.0j
                dr = 0.0j
            else:
                while left == 0:
                    j = (j + 1) % g.shape[0]
                    left = g[j, 1]
                left -= 1
                gait = g[j, 0]
                i = min(t - 1, n_steps - 1)
                if blend and gait != prev and prev >= 0:
                    e = (blend_base + slots[prev * 32 + gait]) * n_steps + i
                    r = blend_rot[e]
                    d = blend_disp[e]
                else:
                    e = (base + gait) * n_steps + i
                    r = rot[e]
                    d = disp[e]
                prev = gait
                dr = drift
            step = d * q
            q = q * r
            p = p + (step + dr)
            b = _block(p.real, p.imag, q.real, q.imag)
            blocks[t] = b
            if b > top:
                top = b
            if t <= keep:
                qs[t] = q
                ps[t] = p
                js[t] = j
                used[t] = g[j, 1] - left
                tops[t] = top
        visits, first = _figures(blocks, budget + 1, top, visits, first, out, k)
    return out


def _compile():
    """The kernel compiled (cached on disk by numba between processes)."""
    global _compiled, _block, _figures, _shared_steps, _transition_pairs
    if _compiled is None:
        import numba

        opts = {"cache": True, "nogil": True}
        _block = numba.njit(**opts)(_block)
        _figures = numba.njit(**opts)(_figures)
        _shared_steps = numba.njit(**opts)(_shared_steps)
        _transition_pairs = numba.njit(**opts)(_transition_pairs)
        _compiled = numba.njit(**opts)(_score_paths)
    return _compiled


def transition_pairs(genes: np.ndarray) -> np.ndarray:
    """The changes of gait id (prev, gait) that turn cycles (P, G, 2) can make within their
    loops, as (n, 2) pairs in increasing order of ``prev * 32 + gait``."""
    _compile()
    mark = np.zeros(32 * 32, dtype=np.bool_)
    _transition_pairs(np.ascontiguousarray(genes, dtype=np.int64), mark)
    return np.stack(np.divmod(np.flatnonzero(mark), 32), axis=-1)


def score_paths(genes: np.ndarray, n_tables: int, moves: np.ndarray, q0: complex, p0: complex,
                drift: complex | None, budget: int,
                transition: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Figures (5, n_tables * P) of turn cycles (P, G, 2) on tables with complex ``moves``
    (n_tables * 32, 2) as ``kinematics.complex_moves`` gives them; path k runs turn cycle
    k % P on table k // P.

    ``transition``: (pairs, blended) for the ``transition`` effect: the changes of gait id
    (n, 2) the turn cycles make (at least those of :func:`transition_pairs`) and, for each
    table and pair, the complex move (n_tables * n, 2) of the blend the first gait cycle after
    that change makes (None: no transition effect)."""
    if transition is None:
        slots = np.zeros(0, dtype=np.int64)
        n_slots = 0
        blended = np.zeros((0, 2), dtype=np.complex128)
    else:
        pairs, blended = transition
        n_slots = len(pairs)
        slots = np.full(32 * 32, -1, dtype=np.int64)
        slots[pairs[:, 0] * 32 + pairs[:, 1]] = np.arange(n_slots)
        if blended.shape != (n_tables * n_slots, 2):
            raise ValueError(f"blended moves {blended.shape}, expected {(n_tables * n_slots, 2)}")
    return score_tabulated(genes, n_tables, np.ascontiguousarray(moves[:, 1]),
                           np.ascontiguousarray(moves[:, 0]), 1, q0, p0, drift, budget, slots,
                           n_slots, np.ascontiguousarray(blended[:, 1]),
                           np.ascontiguousarray(blended[:, 0]))


def score_tabulated(genes: np.ndarray, n_tables: int, rot: np.ndarray, disp: np.ndarray,
                    n_steps: int, q0: complex, p0: complex, drift: complex | None, budget: int,
                    slots: np.ndarray, n_slots: int, blend_rot: np.ndarray,
                    blend_disp: np.ndarray) -> np.ndarray:
    """:func:`score_paths` on moves tabulated as the kernel reads them (flat contiguous complex
    arrays, per step with ``n_steps`` > 1: see ``_score_paths``), which the caller may keep,
    so a search's many small batches do not copy them: the moves per step of
    ``battery_sag``."""
    n = n_tables * 32 * n_steps
    if rot.shape != (n,) or disp.shape != (n,):
        raise ValueError(f"moves {rot.shape}, {disp.shape}, expected {(n,)}")
    if n_slots and (blend_rot.shape[0] < n_tables * n_slots * n_steps
                    or blend_disp.shape != blend_rot.shape or slots.shape != (32 * 32,)):
        raise ValueError("blended moves do not match their slots")
    return _compile()(np.ascontiguousarray(genes, dtype=np.int64), n_tables, rot, disp,
                        n_steps, complex(q0), complex(p0),
                        0j if drift is None else complex(drift), int(budget), slots, n_slots,
                        blend_rot, blend_disp)
