"""Summary plots across a sweep's cells: final coverage per cell, mean learning curves."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pac_host.plots import METHOD_COLOURS, _save, plt
from pac_host.sweep.spec import Cell


def _groups(rows: list[dict]) -> dict[tuple[int, str], list[dict]]:
    out: dict[tuple[int, str], list[dict]] = {}
    for r in rows:
        out.setdefault((r["cell_index"], r["method"]), []).append(r)
    return out


def final_coverage(cells: list[Cell], rows: list[dict], keys: list[str], path: Path) -> Path:
    """Each cell's final operational coverage: one dot per seed, a bar at the mean, the best
    known fitness on its robot dashed."""
    groups = _groups(rows)
    labels = {c.index: c.label(keys) for c in cells}
    order = sorted(groups)
    fig, ax = plt.subplots(figsize=(max(7.0, 0.55 * len(order) + 2), 4.8), dpi=110)
    seen: set[str] = set()
    for x, key in enumerate(order):
        rs = groups[key]
        method = key[1]
        finals = [r["final_coverage"] for r in rs]
        colour = METHOD_COLOURS.get(method, "tab:green")
        jitter = np.linspace(-0.15, 0.15, len(finals)) if len(finals) > 1 else [0.0]
        ax.scatter(x + np.asarray(jitter), finals, s=12, color=colour, alpha=0.7,
                   label=method if method not in seen else None)
        seen.add(method)
        ax.hlines(np.mean(finals), x - 0.3, x + 0.3, color=colour, lw=2.5)
        ax.hlines(rs[0]["best_known"], x - 0.4, x + 0.4, color="k", ls="--", lw=1)
    ax.set_xticks(range(len(order)))
    ax.set_xticklabels([f"{labels[i]} [{m}]" for i, m in order], rotation=35, ha="right",
                       fontsize=7)
    ax.set_ylabel("final coverage fitness on the actual robot")
    ax.set_title("Final operational coverage per cell (dots: seeds; bar: mean; dashed: "
                 "best known)", fontsize=9)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=7, loc="lower right")
    return _save(fig, path)


def mean_curves(cells: list[Cell], rows: list[dict], keys: list[str], path: Path) -> Path:
    """Mean operational coverage against CGA generation, one line per cell and method."""
    groups = _groups(rows)
    labels = {c.index: c.label(keys) for c in cells}
    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=110)
    for (i, method), rs in sorted(groups.items()):
        n = min(len(r["curve_coverage"]) for r in rs)
        mean = np.mean([r["curve_coverage"][:n] for r in rs], axis=0)
        ax.plot(rs[0]["curve_generations"][:n], mean, lw=1.5,
                label=f"{labels[i]} [{method}] ({len(rs)} seeds)" if len(groups) <= 12 else None)
    ax.set_xlabel("CGA generation")
    ax.set_ylabel("mean coverage fitness on the actual robot")
    ax.set_title("Mean operational coverage per cell")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    if len(groups) <= 12:
        ax.legend(fontsize=6, loc="lower right")
    return _save(fig, path)


def sweep_plots(cells: list[Cell], rows: list[dict], keys: list[str], out_dir: Path) -> list[Path]:
    return [final_coverage(cells, rows, keys, out_dir / "final_coverage.png"),
            mean_curves(cells, rows, keys, out_dir / "mean_coverage.png")]
