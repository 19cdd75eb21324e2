"""The sweep's results table: one row per cell, seed and method, as CSV and JSON.

Rows hold the cell's settings, the run's figures (final and mean operational coverage, when
the optimum was reached, the final model error averaged over the 32 gait cycles) and every
other single-valued figure an experiment run reports, so figures added to the experiment
appear here without a change. ``best_known`` is the best fitness any cell of the sweep found
on the same actual robot at the same budget, so cells are compared against one yardstick.
"""

from __future__ import annotations

import csv
import io
import json
from typing import Any

import numpy as np

from pac_host.experiments.sweep.spec import Cell
from pac_host.files import write_atomic

FORMAT = "pac-sweep/1"
CURVES = ("curve_generations", "curve_coverage")  # in the JSON rows, not in the CSV


def _robot_key(cell: Cell) -> str:
    return json.dumps([cell.actual.to_json(), cell.config.pal.budget], sort_keys=True)


def cell_rows(cell: Cell, summary: dict) -> list[dict[str, Any]]:
    """The rows of one finished cell, from its experiment summary."""
    rows = []
    for run in summary["runs"]:
        cov = run["coverage"]
        err = run.get("final_model_error") or []
        row: dict[str, Any] = {"cell": cell.id, "cell_index": cell.index, **cell.settings,
                               "seed": run["seed"], "method": run["method"],
                               "final_coverage": cov[-1] if cov else None,
                               "mean_coverage": round(float(np.mean(cov)), 4) if cov else None,
                               "punctuations": len(cov),
                               "reached_optimum_at": run.get("reached_optimum_at"),
                               "optimum": summary["optimum"],
                               "curve_generations": run["generations"], "curve_coverage": cov}
        for comp in ("F", "T", "dH"):
            row[f"model_error_{comp}"] = (round(float(np.mean([e[comp] for e in err])), 4)
                                          if err else None)
        row.update({k: v for k, v in run.items() if k not in row and _scalar(v)})
        rows.append(row)
    return rows


def _scalar(v: Any) -> bool:
    return v is None or isinstance(v, str | int | float | bool)


def finish_rows(cells: dict[str, Cell], rows: list[dict]) -> list[dict]:
    """Rows in cell, method, seed order, each with the sweep's best known fitness on its robot."""
    best: dict[str, int] = {}
    for r in rows:
        key = _robot_key(cells[r["cell"]])
        best[key] = max(best.get(key, r["optimum"]), r["optimum"])
    out = []
    for r in sorted(rows, key=lambda r: (r["cell_index"], r["method"], r["seed"])):
        b = best[_robot_key(cells[r["cell"]])]
        fin = r["final_coverage"]
        out.append({**r, "best_known": b,
                    "final_over_best_known": round(fin / b, 4) if fin is not None and b else None})
    return out


def columns(rows: list[dict], setting_keys: list[str]) -> list[str]:
    """CSV columns: cell, the settings, then the figures in the order they first appear."""
    cols = ["cell", "cell_index", *setting_keys]
    for r in rows:
        cols += [k for k in r if k not in cols and k not in CURVES]
    return cols


def to_csv(rows: list[dict], setting_keys: list[str]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, columns(rows, setting_keys), extrasaction="ignore",
                       lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _cell_text(v) for k, v in r.items()})
    return buf.getvalue()


def _cell_text(v: Any) -> Any:
    """A CSV cell: lists joined with ';' (an effect's own parameters use ','), None empty."""
    if isinstance(v, list):
        return ";".join(map(str, v))
    return "" if v is None else v


def write_tables(out_dir, cells: list[Cell], rows: list[dict], setting_keys: list[str]) -> None:
    """results.csv and results.json (atomically: a reader never sees half a table)."""
    doc = {"format": FORMAT, "settings": setting_keys,
           "cells": [{"index": c.index, "id": c.id, "settings": c.settings} for c in cells],
           "rows": rows}
    write_atomic(out_dir / "results.json", json.dumps(doc, indent=1) + "\n")
    write_atomic(out_dir / "results.csv", to_csv(rows, setting_keys))
