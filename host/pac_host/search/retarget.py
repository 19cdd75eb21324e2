"""Re-express a turn cycle's path on another model: the same sweep, in that model's gait cycles.

A good sweep is fitted to every row of the table it was found on: the same genes walked on
another robot's table drift off within a pass, and a climb from there ends far below (the best
turn cycles of the built-in robots, each climbed on the others' tables, end at 15-34). What does
carry over is the path's shape: where the sweep turns, how far it goes between, where each pass
ends. :func:`retarget` picks, gene after gene, the (gait id, repetitions) of the target table
whose move brings the walk closest to where the source's walk is at the end of that gene
(displacement in cm plus :data:`WEIGHT` times the rotation, as the closing kicks weigh them),
keeping the ``beam`` closest partial walks. The loop's last gene then also closes the pass where
the source's does, so a repeating sweep repeats on the target too.

Only the table's moves are used (its table effects applied; sequence effects and world drift
left out): it proposes starting points, and every proposal is scored by the coverage simulator.

>>> from pac_host.coverage import parse_turn_cycle, simulate
>>> from pac_host.model import measured_table, shifted_table
>>> from pac_host.search.kicks import loop_table
>>> x = parse_turn_cycle("31:3,13:2,23:12,21:7,5:8,5:1,11:2,8:7,1:1")  # 44 on the measured table
>>> m, s = measured_table().rows, shifted_table().rows
>>> int(simulate(s, x, 200).fitness[0])  # the same genes on the shifted robot
4
>>> y = retarget(x, loop_table(m), loop_table(s))
>>> int(simulate(s, y[:1], 200).fitness[0])  # the same path on the shifted robot
44
"""

from __future__ import annotations

import numpy as np

from pac_host.search.kicks import WEIGHT
from pac_host.search.neighbours import _VALUES

BEAM = 50  # partial walks kept at each gene; every one of the last is a proposal


def retarget(genes: np.ndarray, source: np.ndarray, target: np.ndarray, beam: int = BEAM,
             weight: float = WEIGHT) -> np.ndarray:
    """Turn cycles (B, G, 2) on the ``target`` table that walk the path ``genes`` (G, 2) walks on
    the ``source`` table, closest first (B <= ``beam``). ``source`` and ``target`` are the
    tables' moves repeated 0..63 times (:func:`pac_host.search.kicks.loop_table`). Each gene is
    matched by the walk's end after it, from the start, so errors do not pile up along the loop;
    an empty gene stays empty."""
    genes = np.asarray(genes, dtype=np.int64)
    values = _VALUES[_VALUES[:, 1] > 0]
    moves = target[values[:, 0], values[:, 1]]  # (V, 2): displacement, rotation
    walk = np.array([0j, 1 + 0j])  # the source's walk so far
    ends = walk[None].copy()  # (B, 2): each partial walk's end on the target
    chosen = np.zeros((1, 0, 2), dtype=np.int64)
    errors = np.zeros(1)
    for gid, reps in genes:
        if reps == 0:
            chosen = np.concatenate([chosen, np.zeros((len(chosen), 1, 2), np.int64)], axis=1)
            continue
        step = source[gid, reps]
        walk = np.array([walk[0] + walk[1] * step[0], walk[1] * step[1]])
        disp = ends[:, None, 0] + ends[:, None, 1] * moves[None, :, 0]  # (B, V)
        rot = ends[:, None, 1] * moves[None, :, 1]
        err = errors[:, None] + np.abs(disp - walk[0]) + weight * np.abs(rot - walk[1])
        k = min(beam, err.size)
        flat = np.argpartition(err.ravel(), k - 1)[:k]
        flat = flat[np.argsort(err.ravel()[flat], kind="stable")]
        b, v = np.divmod(flat, len(values))
        chosen = np.concatenate([chosen[b], values[v][:, None]], axis=1)
        ends = np.stack([disp[b, v], rot[b, v]], axis=-1)
        errors = err[b, v]
    return chosen
