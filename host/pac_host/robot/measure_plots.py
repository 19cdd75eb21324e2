"""PNG of a measured gait table against the current one: per id and component, the
difference with its standard-error bars (what `pac-host measure` shows)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pac_host.plots import _save, plt


def table_differences(ids: Sequence[int], diff: np.ndarray, se: np.ndarray, path: Path,
                      title: str = "Measured minus current table") -> Path:
    """``diff`` and ``se`` are (len(ids), 3): F cm, T cm, dH deg."""
    ids = np.asarray(ids)
    fig, axes = plt.subplots(3, 1, figsize=(8, 6.5), dpi=110, sharex=True)
    for j, (ax, name, unit) in enumerate(zip(axes, ("F", "T", "dH"), ("cm", "cm", "deg"),
                                             strict=True)):
        big = np.abs(diff[:, j]) > 3 * se[:, j]
        colours = np.where(big, "tab:red", "tab:blue")
        ax.bar(ids, diff[:, j], color=colours, alpha=0.7)
        ax.errorbar(ids, diff[:, j], yerr=3 * se[:, j], fmt="none", ecolor="k", lw=0.8,
                    capsize=2)
        ax.axhline(0, color="k", lw=0.6)
        ax.set_ylabel(f"{name} ({unit})")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("gait cycle id (bars: measured - current; whiskers: 3 standard "
                        "errors; red: beyond them)")
    axes[-1].set_xticks(ids)
    axes[-1].tick_params(axis="x", labelsize=7)
    axes[0].set_title(title)
    return _save(fig, path)
