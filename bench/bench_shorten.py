"""Listing a stalled loop's shorter windows: the compiled search for matching pairs against
SciPy's KD-trees.

A search chain that stalls lists every re-setting of four consecutive genes that shortens its
loop and keeps the window's move (``pac_host.search.shorten.shorter_windows``); in PAL's
default profile that listing was 43% of a run's time (sampled from a library_on_changed run,
seeds 0-1), nearly all of it in the KD-trees' pairing. For each built-in robot, its best known
loop and the other robots' best known loops are listed on its table, as a chain meets them:
the pairs of a table made once, for its first loop, then kept. Both ways find the same
proposals in the same order (checked here too, and by tests/search/test_shorter_windows.py).
Reported: seconds per loop each way (the better of ``REPEATS``), and how many times faster the
compiled one is. Target: at least 3 times faster over all loops (a ratio on one machine, so it
holds on a slow one as well as a fast one).

Usage: ``python bench/run.py --only shorten`` (about four minutes on an idle machine;
``--quick``: one robot, once).
"""

from __future__ import annotations

import json
import time

import known_best
import numpy as np

from pac_host.coverage import parse_turn_cycle
from pac_host.model import robots, shifted_table
from pac_host.search import shorten
from pac_host.search.kicks import loop_table

REPEATS = 2
TARGET = 3.0


def _loops() -> list[np.ndarray]:
    return [parse_turn_cycle(rec["turn_cycle"]) for rec in known_best.entries().values()]


def _list_all(repeated: np.ndarray, loops: list[np.ndarray], matches) -> tuple[float, list]:
    """Seconds to list every loop's windows on one table, the pairs made afresh for the
    first, and the proposals."""
    shorten._pairs_kept.clear()
    t0 = time.perf_counter()
    out = [shorten.shorter_windows(x, repeated, 200, matches=matches) for x in loops]
    return time.perf_counter() - t0, out


def run(quick: bool = False) -> dict:
    tables = {"shifted": shifted_table(), **{n: robots.build(n) for n in robots.ROBOTS}}
    if quick:
        tables = {"shifted": tables["shifted"]}
    loops = _loops()
    shorten.shorter_windows(loops[0], loop_table(shifted_table().rows), 200)  # compiled now
    per: dict = {}
    total = {"tree": 0.0, "compiled": 0.0}
    for name, table in tables.items():
        repeated = loop_table(table.rows, table.effects)
        best: dict = {}
        for way, matches in (("tree", shorten._tree_matches),
                             ("compiled", shorten._band_matches)):
            runs = [_list_all(repeated, loops, matches) for _ in range(1 if quick else REPEATS)]
            best[way] = min(r[0] for r in runs)
            best[way + "_proposals"] = runs[0][1]
        same = all(np.array_equal(a, b) for a, b in zip(best["tree_proposals"],
                                                         best["compiled_proposals"],
                                                         strict=True))
        per[name] = {"loops": len(loops),
                     "proposals": int(sum(len(p) for p in best["compiled_proposals"])),
                     "tree_s_per_loop": round(best["tree"] / len(loops), 3),
                     "compiled_s_per_loop": round(best["compiled"] / len(loops), 3),
                     "same_proposals": same}
        for way in total:
            total[way] += best[way]
    ratio = total["tree"] / total["compiled"]
    return {"robots": per, "times_faster": round(ratio, 2),
            "targets": {
                "compiled_at_least_3x_faster": {"value": round(ratio, 2), "target": ">= 3",
                                                "met": ratio >= TARGET},
                "same_proposals": {"value": all(r["same_proposals"] for r in per.values()),
                                   "target": "true",
                                   "met": all(r["same_proposals"] for r in per.values())}}}


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
