"""Summary plots across a sweep's cells: final coverage per cell, mean learning curves."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pac_host.experiments.sweep.spec import Cell
from pac_host.plots import METHOD_COLOURS, _save, plt, progress_axis


def _groups(rows: list[dict]) -> dict[tuple[int, str], list[dict]]:
    out: dict[tuple[int, str], list[dict]] = {}
    for r in rows:
        out.setdefault((r["cell_index"], r["method"]), []).append(r)
    return out


def _name(labels: dict[int, str], cells_methods: dict[int, set], i: int, method: str) -> str:
    return labels[i] + (f" [{method}]" if len(cells_methods[i]) > 1 else "")


def final_coverage(cells: list[Cell], rows: list[dict], keys: list[str], path: Path) -> Path:
    """Each cell's final operational coverage, one line per cell (and method): a dot per
    seed, a bar at the mean, the best known fitness on its robot dashed."""
    groups = _groups(rows)
    labels = {c.index: c.label(keys) for c in cells}
    methods = {c.index: set(c.config.methods) for c in cells}
    order = sorted(groups)
    fig, ax = plt.subplots(figsize=(8.5, max(2.5, 0.32 * len(order) + 1.4)), dpi=110)
    seen: set[str] = set()
    for y, key in enumerate(order):
        rs = groups[key]
        method = key[1]
        finals = [r["final_coverage"] for r in rs]
        colour = METHOD_COLOURS.get(method, "tab:green")
        jitter = np.linspace(-0.15, 0.15, len(finals)) if len(finals) > 1 else [0.0]
        ax.scatter(finals, y + np.asarray(jitter), s=12, color=colour, alpha=0.7,
                   label=method if method not in seen else None)
        seen.add(method)
        ax.vlines(np.mean(finals), y - 0.3, y + 0.3, color=colour, lw=2.5)
        ax.vlines(rs[0]["best_known"], y - 0.4, y + 0.4, color="k", ls="--", lw=1)
    ax.set_yticks(range(len(order)))
    ax.set_yticklabels([_name(labels, methods, i, m) for i, m in order], fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("final coverage fitness on the actual robot")
    ax.set_title("Final coverage per cell: dots seeds, bar mean, dashed best known",
                 fontsize=9)
    ax.set_xlim(left=0)
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=7, loc="best")
    return _save(fig, path)


def mean_curves(cells: list[Cell], rows: list[dict], keys: list[str], path: Path) -> Path:
    """Mean operational coverage against CGA generation, one line per cell and method; against
    punctuation where a cell ran no CGA between punctuations (an anytime search)."""
    # one axis for every cell: the CGA's generations only if the CGA ran in all of them
    search = "cga" if all(c.config.pal.search == "cga" for c in cells) else "anytime"
    groups = _groups(rows)
    labels = {c.index: c.label(keys) for c in cells}
    methods = {c.index: set(c.config.methods) for c in cells}
    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=110)
    for (i, method), rs in sorted(groups.items()):
        n = min(len(r["curve_coverage"]) for r in rs)
        mean = np.mean([r["curve_coverage"][:n] for r in rs], axis=0)
        name = f"{_name(labels, methods, i, method)} ({len(rs)} seeds)"
        x, _ = progress_axis(search, rs[0]["curve_generations"][:n])
        ax.step(x, mean, where="post", lw=1.5, label=name if len(groups) <= 12 else None)
    ax.set_xlabel(progress_axis(search, ())[1])
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
