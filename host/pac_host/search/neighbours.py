"""The single-gene neighbourhood of a turn cycle, without the changes that cannot matter.

A neighbour changes one gene to any (gait id, repetitions). Changes that give the same walk are
left out: a gene the budget never reaches in the loop's first pass is inert, a gene with 0
repetitions has no id, and filling any one of a run of empty slots between the same two genes
gives the same loop. What remains (at most 9 x (32 x 63 + 1) neighbours) is evaluated in one
batched call of the coverage simulator.

>>> import numpy as np
>>> from pac_host.coverage import parse_turn_cycle
>>> n = neighbours(parse_turn_cycle("12:60,3:10"), budget=200)
>>> n.shape[1:], len(n)  # two active genes, and one slot to fill after them
((9, 2), 6048)
"""

from __future__ import annotations

import functools
import itertools

import numpy as np

from pac_host.coverage import MAX_GAIT_ID, MAX_REPS

# Every (id, repetitions) a gene may take with repetitions > 0, and the empty gene.
_VALUES = np.array([(i, r) for i in range(MAX_GAIT_ID + 1) for r in range(1, MAX_REPS + 1)]
                   + [(0, 0)], dtype=np.int64)
_INDICES = np.arange(len(_VALUES))


def canonical(genes: np.ndarray, budget: int) -> np.ndarray:
    """Turn cycles (..., G, 2) with inert genes blanked to (0, 0): empty genes lose their id,
    and genes the budget never reaches in the first pass are emptied. The walk is unchanged."""
    out = np.array(genes, dtype=np.int64, copy=True)
    reps = out[..., 1]
    starts = np.cumsum(reps, axis=-1) - reps
    inert = (reps == 0) | (starts >= budget)
    out[inert] = 0
    return out


def slots(genes: np.ndarray, budget: int) -> np.ndarray:
    """Indices of the genes worth changing: every reached gene and the first of each run of
    empty slots the budget reaches."""
    reps = genes[:, 1]
    starts = np.cumsum(reps) - reps
    reached = starts < budget
    empty = reps == 0
    first_empty = empty & np.concatenate(([True], ~empty[:-1]))
    return np.flatnonzero(reached & (~empty | first_empty))


def value_indices(gene: np.ndarray, small: bool = False) -> np.ndarray:
    """Indices into the table of gene values of every value a gene (id, repetitions) can
    change to, in the table's order; with ``small``, only those keeping its id or its
    repetitions (for a non-empty gene)."""
    gid, reps = int(gene[0]), int(gene[1])
    if small and reps > 0:
        return _small_changes(gid, reps)
    k = len(_VALUES) - 1 if reps == 0 else gid * MAX_REPS + reps - 1
    return np.concatenate((_INDICES[:k], _INDICES[k + 1:]))


@functools.lru_cache(maxsize=len(_VALUES))
def _small_changes(gid: int, reps: int) -> np.ndarray:
    """The values keeping id ``gid`` or ``reps`` repetitions (computed once each, read-only)."""
    same_reps = np.arange(MAX_GAIT_ID + 1) * MAX_REPS + reps - 1
    same_id = gid * MAX_REPS + np.arange(MAX_REPS)
    idx = np.union1d(same_reps, same_id)
    if gid == 0:
        idx = np.append(idx, len(_VALUES) - 1)  # the empty gene keeps id 0
    idx = idx[idx != gid * MAX_REPS + reps - 1]
    idx.flags.writeable = False
    return idx


def gene_changes(genes: np.ndarray, j: int, idx: np.ndarray) -> np.ndarray:
    """Copies of a canonical turn cycle with gene ``j`` set to each value ``idx`` names."""
    block = np.repeat(genes[None], len(idx), axis=0)
    block[:, j] = _VALUES[idx]
    return block


def neighbours(genes: np.ndarray, budget: int, only: int | None = None,
               small: bool = False) -> np.ndarray:
    """All distinct single-gene changes of one turn cycle (9, 2), as a (N, 9, 2) array; with
    ``only``, the changes of that gene alone; with ``small``, only those that keep the gene's
    id or its repetitions (at most 94 a gene instead of 2,016)."""
    genes = canonical(genes, budget)
    parts = [gene_changes(genes, j, value_indices(genes[j], small))
             for j in (slots(genes, budget) if only is None else [only])]
    if not parts:
        return np.empty((0,) + genes.shape, dtype=np.int64)
    return np.concatenate(parts)


def pair_neighbours(genes: np.ndarray, budget: int, span: int = 3) -> np.ndarray:
    """Changes of the repetitions of two reached genes at once, each by -span..span (not both
    0): the compensating changes (one sweep longer, another shorter) that a single-gene
    change cannot make without first getting worse."""
    genes = canonical(genes, budget)
    active = [j for j in slots(genes, budget) if genes[j, 1] > 0]
    d = np.arange(-span, span + 1)
    da, db = (a.ravel() for a in np.meshgrid(d, d, indexing="ij"))
    keep = (da != 0) | (db != 0)
    da, db = da[keep], db[keep]
    if len(active) < 2:
        return np.empty((0,) + genes.shape, dtype=np.int64)
    # every pair (i < j) of active genes, then every (da, db), in that order (a climb takes
    # the first of equal scores), built in one go: a climb asks for this at every look
    i, j = (np.array(v) for v in zip(*itertools.combinations(active, 2), strict=True))
    ri = genes[i, 1][:, None] + da  # (pairs, deltas): the new repetitions of genes i and j
    rj = genes[j, 1][:, None] + db
    pair, delta = np.nonzero((ri >= 1) & (ri <= MAX_REPS) & (rj >= 1) & (rj <= MAX_REPS))
    out = np.repeat(genes[None], len(pair), axis=0)
    k = np.arange(len(pair))
    out[k, i[pair], 1] = ri[pair, delta]
    out[k, j[pair], 1] = rj[pair, delta]
    return out
