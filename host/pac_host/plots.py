"""PNG plots a person looks at: learning curves in the style of the paper's Figures 6-8.

Rendering uses matplotlib's Agg backend (files only, no display needed).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

METHOD_TITLES = {
    "full": "PAL without partial recombination (full)",
    "partial": "PAL with partial recombination",
}
METHOD_COLOURS = {"full": "tab:red", "partial": "tab:blue"}


def coverage_per_seed(summary: dict, method: str, path: Path) -> Path:
    """Operational coverage on the actual robot against CGA generation, one line per seed."""
    runs = [r for r in summary["runs"] if r["method"] == method]
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=110)
    for r in runs:
        ax.step(r["generations"], r["coverage"], where="post", lw=1.2, alpha=0.8,
                label=f"seed {r['seed']}" if len(runs) <= 10 else None)
    _decorate(ax, summary, METHOD_TITLES.get(method, method) + f" ({len(runs)} seeds)")
    if len(runs) <= 10:
        ax.legend(fontsize=7, ncol=2, loc="lower right")
    return _save(fig, path)


def mean_coverage(summary: dict, path: Path) -> Path:
    """The methods' mean operational coverage against CGA generation (paper's Figure 8)."""
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=110)
    comp = summary["comparison"]["methods"]
    for method, m in comp.items():
        gens = next(r["generations"] for r in summary["runs"] if r["method"] == method)
        ax.plot(gens, m["mean_coverage"], lw=2, color=METHOD_COLOURS.get(method),
                label=f"{method}: {m['reached_optimum']}/{m['seeds']} reached the optimum")
    _decorate(ax, summary, "Mean operational coverage over seeds")
    ax.legend(fontsize=8, loc="lower right")
    return _save(fig, path)


def _decorate(ax, summary: dict, title: str) -> None:
    ax.axhline(summary["optimum"], color="k", ls="--", lw=1, label="optimum on the actual robot")
    ax.set_xlabel("CGA generation")
    ax.set_ylabel("coverage fitness on the actual robot (3R + c)")
    ax.set_title(title)
    ax.set_ylim(bottom=0, top=summary["optimum"] + 2)
    ax.grid(alpha=0.3)


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def experiment_plots(summary: dict, out_dir: Path) -> list[Path]:
    """All three figures for an experiment summary; returns their paths."""
    paths = [coverage_per_seed(summary, m, out_dir / f"coverage_{m}.png")
             for m in summary["config"]["methods"]]
    paths.append(mean_coverage(summary, out_dir / "coverage_means.png"))
    return paths
