"""Turn cycles (DESIGN.md 2.2): their text form, limits and budget, and how one loops over the
budget's gait cycles.

A turn cycle is up to 9 genes (gait cycle id, repetitions), looped until the budget of gait
cycles is spent; a gene with 0 repetitions is skipped.

>>> genes = parse_turn_cycle("12:2,3:1")
>>> format_turn_cycle(genes), expand(genes[None], 5)[0].tolist()
('12:2,3:1', [[12, 12, 3, 12, 12]])
"""

from __future__ import annotations

import re

import numpy as np

from pac_host.errors import InputError
from pac_host.limits import SIM_BUDGET
from pac_protocol.messages import MAX_GAIT as MAX_GAIT_ID  # the wire's limits are the genes'
from pac_protocol.messages import MAX_GENES, MAX_REPS

DEFAULT_BUDGET = 200


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
    """``budget`` as an int if it is a gait-cycle count the robot can run (0..65535)."""
    return SIM_BUDGET.check(budget, "budget")


# Entries of a chunk's step table ahead of the genes': the leading one of the heading scan,
# the start pose, and standing still (a turn cycle with no repetitions at all).
_ONE, _START, _STILL = 0, 1, 2
_FIRST_GENE = 3
_POSITIONS_CACHED_UP_TO = 1024  # budgets whose loop-position table is kept (568 x budget)
_positions: dict[int, np.ndarray] = {}


def _loop_positions(loop_len: np.ndarray, budget: int, out: np.ndarray) -> None:
    """``out[p, t] = t mod loop_len[p]`` (0 for empty loops), by lookup for common budgets:
    integer modulo is the slowest numpy operation there is."""
    top = MAX_GENES * MAX_REPS
    if budget > _POSITIONS_CACHED_UP_TO or loop_len.size and loop_len.max() > top:
        np.remainder(np.arange(budget), np.maximum(loop_len, 1)[:, None], out=out)
        return
    table = _positions.get(budget)
    if table is None:
        if len(_positions) >= 4:  # a budget sweep must not keep a table per budget
            _positions.clear()
        lengths = np.maximum(np.arange(top + 1), 1)[:, None]
        table = _positions[budget] = np.arange(budget) % lengths
    np.take(table, loop_len, axis=0, out=out, mode="clip")


def _step_entries(genes: np.ndarray, budget: int, out: np.ndarray, pos: np.ndarray,
                  first: np.ndarray) -> np.ndarray:
    """Which gene each looped turn cycle executes at each of its ``budget`` steps.

    ``genes`` (P, G, 2); fills ``out`` (P, budget) with the entry ``_FIRST_GENE + p G + g`` of
    gene g of path p, or ``_STILL`` for a turn cycle with no repetitions, using ``pos`` and
    ``first`` (P, budget) as scratch. Returns the (P,) mask of such still turn cycles.
    """
    reps = genes[..., 1]
    n_paths, n_genes = reps.shape
    loop_len = reps.sum(axis=-1)
    still = loop_len == 0
    # the first pass of each loop (up to the budget) as a step function: mark where each gene
    # starts with the change of entry there, then an integer cumulative sum, which is cheap
    # and, unlike np.repeat, writes into a reused array
    starts = np.cumsum(reps, axis=-1) - reps
    path, gene = np.nonzero((reps > 0) & (starts < budget))
    entry = _FIRST_GENE + path * n_genes + gene
    change = np.diff(entry, prepend=0)
    new_path = np.diff(path, prepend=-1) != 0
    change[new_path] = entry[new_path]
    first.fill(0)
    first[path, starts[path, gene]] = change
    np.cumsum(first, axis=1, out=first)
    _loop_positions(loop_len, budget, pos)
    pos += (np.arange(n_paths) * budget)[:, None]
    np.take(first.ravel(), pos, out=out, mode="clip")
    if still.any():
        out[still] = _STILL
    return still


def expand(genes: np.ndarray, budget: int) -> tuple[np.ndarray, np.ndarray]:
    """Gait ids executed by each looped turn cycle: genes (P, G, 2) -> ids (P, budget).

    Also returns a (P,) mask of turn cycles with no repetitions at all, which stand still
    (their ids are 0).
    """
    genes = np.asarray(genes)
    shape = (genes.shape[0], budget)
    steps, pos, first = (np.empty(shape, dtype=np.intp) for _ in range(3))
    still = _step_entries(genes, budget, steps, pos, first)
    ids = np.concatenate((np.zeros(_FIRST_GENE, dtype=genes.dtype), genes[..., 0].ravel()))
    return ids[steps], still
