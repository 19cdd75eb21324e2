"""PNG plots a person looks at: learning curves in the style of the paper's Figures 6-8.

Rendering uses matplotlib's Agg backend (files only, no display needed).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from pac_host.errors import InputError  # noqa: E402
from pac_host.files import make_dirs, write_atomic_with  # noqa: E402

METHOD_TITLES = {
    "full": "PAL without partial recombination (full)",
    "partial": "PAL with partial recombination",
    "oracle": "control: the CGA on the actual robot's own table",
}
METHOD_COLOURS = {"full": "tab:red", "partial": "tab:blue", "oracle": "tab:gray"}
CGA_AXIS = "CGA generation"
PUNCTUATION_AXIS = "punctuations (3 robot tests each)"


def progress_axis(search: str, generations) -> tuple[list, str]:
    """The x values and label of a curve over a run's punctuations, for what ran between
    them (``search``, a PAL config's): the CGA's generations where the CGA ran, else the
    punctuations counted from 1 (an anytime search counts no generations).

    >>> progress_axis("cga", [0, 40, 80])
    ([0, 40, 80], 'CGA generation')
    >>> progress_axis("ils", [0, 40, 80])
    ([1, 2, 3], 'punctuations (3 robot tests each)')
    """
    if search == "cga":
        return list(generations), CGA_AXIS
    return list(range(1, len(generations) + 1)), PUNCTUATION_AXIS


def method_title(method: str, pal_config: dict) -> str:
    """A method's name in a figure, for what ran: with no model GA (recombination inert) the
    PAL method is the model fitted to every observed step, not partial recombination."""
    from pac_host.learning.config import recombination_inert

    if method == "partial" and recombination_inert(pal_config):
        return "PAL, the model fitted to every observed step (no model GA)"
    return METHOD_TITLES.get(method, method)


def coverage_per_seed(summary: dict, method: str, path: Path) -> Path:
    """Operational coverage on the actual robot against CGA generation (or punctuation, where
    no CGA ran between them), one line per seed."""
    runs = [r for r in summary["runs"] if r["method"] == method]
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=110)
    for r in runs:
        x, _ = progress_axis(summary["pal_config"]["search"], r["generations"])
        ax.step(x, r["coverage"], where="post", lw=1.2, alpha=0.8,
                label=f"seed {r['seed']}" if len(runs) <= 10 else None)
    _decorate(ax, summary, method_title(method, summary["pal_config"])
              + f" ({len(runs)} seeds)")
    if len(runs) <= 10:
        ax.legend(fontsize=7, ncol=2, loc="lower right")
    return _save(fig, path)


def mean_coverage(summary: dict, path: Path) -> Path:
    """The methods' mean operational coverage against CGA generation (or punctuation)
    (paper's Figure 8)."""
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=110)
    comp = summary["comparison"]["methods"]
    for method, m in comp.items():
        gens = next(r["generations"] for r in summary["runs"] if r["method"] == method)
        x, _ = progress_axis(summary["pal_config"]["search"], gens)
        name = ("oracle (perfect model)" if method == "oracle"
                else "PAL, model fitted" if method_title(method, summary["pal_config"])
                != METHOD_TITLES.get(method) else method)
        ax.plot(x, m["mean_coverage"], lw=2, color=METHOD_COLOURS.get(method),
                label=f"{name}: {m['reached_optimum']}/{m['seeds']} reached the optimum")
    _decorate(ax, summary, "Mean operational coverage over seeds")
    ax.legend(fontsize=8, loc="lower right")
    return _save(fig, path)


def _x_label(ax, label: str) -> None:
    """The x axis's label; punctuations are counted, so their ticks are whole numbers."""
    ax.set_xlabel(label)
    if label == PUNCTUATION_AXIS:
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def _wrapped(text: str, width: int) -> str:
    """Each line of ``text`` folded to ``width`` characters, so a long title stays on the
    figure; a turn cycle is never split.

    >>> _wrapped("walked on the robot 29:9,19:36,23:20", 20)
    'walked on the robot\\n29:9,19:36,23:20'
    """
    return "\n".join(textwrap.fill(line, width, break_long_words=False, break_on_hyphens=False)
                     for line in text.split("\n"))


def _figures(summary: dict) -> str:
    """A y label's note on a noisy actual robot: the figures are expectations."""
    figures = summary.get("figures", "one walk")
    return "" if figures == "one walk" else f"\n{figures}"


def _decorate(ax, summary: dict, title: str) -> None:
    ax.axhline(summary["optimum"], color="k", ls="--", lw=1,
               label="the experiment's optimum on the actual robot")
    _x_label(ax, progress_axis(summary["pal_config"]["search"], ())[1])
    ax.set_ylabel("coverage fitness on the actual robot (3R + c)" + _figures(summary))
    ax.set_title(title)
    ax.set_ylim(bottom=0, top=summary["optimum"] + 2)
    ax.grid(alpha=0.3)


def _save(fig, path: Path) -> Path:
    """Write the figure whole (through a temporary file renamed over, as result files are):
    a full disk or a folder that may not be written is one line naming the plot, and leaves
    no half PNG and every other file as it was."""
    try:
        kind = path.suffix.lstrip(".").lower() or "png"
        if kind not in fig.canvas.get_supported_filetypes():
            raise InputError(f"{path}: a plot is written as .png, .svg or .pdf, not .{kind}")
        make_dirs(path.parent)
        fig.tight_layout()
        write_atomic_with(path, lambda f: fig.savefig(f, format=kind))
    finally:
        plt.close(fig)
    return path


def experiment_plots(summary: dict, out_dir: Path) -> list[Path]:
    """All three figures for an experiment summary; returns their paths."""
    paths = [coverage_per_seed(summary, m, out_dir / f"coverage_{m}.png")
             for m in summary["config"]["methods"]]
    paths.append(mean_coverage(summary, out_dir / "coverage_means.png"))
    if "robot_time" in summary:
        paths.append(robot_time(summary, out_dir / "robot_time.png"))
    return paths


def robot_time(summary: dict, path: Path) -> Path:
    """Median and range over seeds of the operational coverage, per method, against
    punctuations (robot tests) and against robot hours, with the target line."""
    import numpy as np

    rt = summary["robot_time"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), dpi=110, sharey=True)
    for method in rt["methods"]:
        runs = [r for r in summary["runs"] if r["method"] == method]
        cov = np.array([r["coverage"] for r in runs], dtype=float)
        hours = np.median(np.array([r["robot_hours"] for r in runs], dtype=float), axis=0)
        med, lo, hi = np.median(cov, axis=0), cov.min(axis=0), cov.max(axis=0)
        n = np.arange(1, cov.shape[1] + 1)
        colour = METHOD_COLOURS.get(method)
        for ax, x in ((axes[0], n), (axes[1], hours)):
            ax.step(x, med, where="post", lw=2, color=colour, label=f"{method}: median")
            ax.fill_between(x, lo, hi, step="post", alpha=0.2, color=colour)
    for ax, label in ((axes[0], "punctuations (3 robot tests each)"),
                      (axes[1], "robot hours (median over seeds)")):
        ax.axhline(rt["best_known"], color="k", ls="--", lw=1, label="best known")
        ax.axhline(rt["target"] * rt["best_known"], color="k", ls=":", lw=1,
                   label=f"{rt['target']:.0%} of the best known")
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("operational coverage on the actual robot (3R + c)"
                       + _figures(summary))
    axes[0].set_ylim(0, rt["best_known"] + 2)
    axes[0].legend(fontsize=7, loc="lower right")
    fig.suptitle("Operational coverage against robot time: median and range over seeds")
    return _save(fig, path)


def coverage_path(poses, blocks, path: Path, title: str = "Coverage path",
                  figures: dict | None = None, walks=None) -> Path:
    """The path on the area: 60 cm blocks with their mines, the body width at each detection,
    found mines in green and missed ones in red; ``walks`` (k, n + 1, 3), other walks of the
    same turn cycle (a noisy robot's), drawn thin beneath it to show their spread."""
    import numpy as np
    from matplotlib.patches import Rectangle

    from pac_host.coverage import BLOCK_CM, COLUMNS, HALF_BODY_CM

    poses = np.asarray(poses)
    blocks = np.asarray(blocks)
    walks = np.empty((0,) + poses.shape) if walks is None else np.asarray(walks)
    top_y = max(poses[:, 1].max(), walks[..., 1].max(initial=0.0), 0)
    top_row = max(int(top_y // BLOCK_CM) + 1, 3)
    height_cm = top_row * BLOCK_CM + 30
    fig, ax = plt.subplots(figsize=(4.2, min(1.2 + 3.6 * height_cm / 220, 16)), dpi=110)
    found = set(blocks[blocks >= 0].tolist())
    for r in range(top_row):
        for c in range(COLUMNS):
            ax.add_patch(Rectangle((c * BLOCK_CM, r * BLOCK_CM), BLOCK_CM, BLOCK_CM, fill=False,
                                   lw=0.8, ec="0.6"))
            hit = r * COLUMNS + c in found
            ax.plot((c + 0.5) * BLOCK_CM, (r + 0.5) * BLOCK_CM, marker="*", ms=9,
                    color="tab:green" if hit else "tab:red", zorder=3)
    for w in walks:
        ax.plot(w[:, 0], w[:, 1], "-", color="tab:gray", lw=0.4, alpha=0.5, zorder=1)
    ax.plot(poses[:, 0], poses[:, 1], "-", color="tab:blue", lw=1, zorder=2)
    det = blocks >= 0
    rad = np.radians(poses[det, 2])
    dx, dy = HALF_BODY_CM * np.cos(rad), -HALF_BODY_CM * np.sin(rad)
    for (x, y), ex, ey in zip(poses[det, :2], dx, dy, strict=True):
        ax.plot([x - ex, x + ex], [y - ey, y + ey], color="tab:green", lw=1.5, alpha=0.6)
    ax.plot(*poses[0, :2], "ko", ms=5, label="start")
    ax.set_xlim(-20, COLUMNS * BLOCK_CM + 20)
    ax.set_ylim(-20, top_row * BLOCK_CM + 10)
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    if figures:
        title += (f"\ncovered {figures['blocks_covered']}, once {figures['blocks_covered_once']},"
                  f" fitness {figures['fitness']}")
    ax.set_title(_wrapped(title, 48), fontsize=9)
    return _save(fig, path)


def learning_progress(records: list[dict], path: Path, title: str = "Learning progress",
                      search: str = "cga") -> Path:
    """Operational coverage on the robot and the model's error, per punctuation: against the
    CGA's generations where ``search`` (what ran between punctuations) is the CGA."""
    from pac_host.learning.model_ga import ERROR_UNITS

    gens, x_label = progress_axis(search, [r["generation"] for r in records])
    fig, ax = plt.subplots(figsize=(7, 4), dpi=110)
    expected = operational_expectation(records)
    if expected is None:
        ax.step(gens, [r["operational_fitness"] for r in records], where="post", lw=2,
                label="operational coverage on the robot (one walk: the robot is exact)")
    else:  # a noisy robot: what the operational turn cycle delivers, with its interval
        mean, lo, hi, walks = expected
        ax.step(gens, mean, where="post", lw=2,
                label=f"operational: expected coverage on the robot, 95% interval "
                      f"({walks} walks behind the last)")
        ax.fill_between(gens, lo, hi, step="post", alpha=0.25)
        ax.plot(gens, [r["operational_fitness"] for r in records], ".", ms=4, color="tab:blue",
                label="operational: its last walk")
    ax.plot(gens, [r["observed"][0]["fitness"] for r in records], "o", ms=4,
            label="tested best turn cycle on the robot")
    ax.plot(gens, [r["predicted"][0]["fitness"] for r in records], "x", ms=5,
            label="same, predicted by the model")
    _x_label(ax, x_label)
    ax.set_ylabel("coverage fitness (3R + c)")
    ax2 = ax.twinx()
    ax2.plot(gens, [r["model_error_before"] for r in records], color="tab:gray", lw=1, ls=":",
             label="model error on the new tests")
    fitness = records[-1].get("model_fitness", "coverage") if records else "coverage"
    ax2.set_ylabel(_wrapped(f"model error, {ERROR_UNITS[fitness]}", 45), fontsize=7)
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=7, loc="upper left")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def operational_expectation(records: list[dict]
                            ) -> tuple[list[float], list[float], list[float], int] | None:
    """The operational turn cycle's expected coverage per punctuation as a noisy run logs it
    (``operational_estimate``): means, 95% interval bounds (the mean where one walk gives no
    interval) and the walks behind the last; None where every estimate is exact (a robot
    without step noise: its one walk is the figure).

    >>> operational_expectation([{"operational_estimate": {"mean": 20.0,
    ...     "interval": [18.5, 21.5], "walks": 3}}])
    ([20.0], [18.5], [21.5], 3)
    >>> operational_expectation([{"operational_estimate": {"mean": 20.0,
    ...     "interval": [20.0, 20.0], "walks": 1}}]) is None
    True
    """
    est = [r.get("operational_estimate") for r in records]
    if not est or any(e is None for e in est):
        return None
    spread = [e["interval"] for e in est if e.get("interval") is not None]
    if not any(lo < hi for lo, hi in spread):
        return None
    mean = [float(e["mean"]) for e in est]
    lo = [float(e["interval"][0]) if e.get("interval") else m for e, m in zip(est, mean,
                                                                              strict=True)]
    hi = [float(e["interval"][1]) if e.get("interval") else m for e, m in zip(est, mean,
                                                                              strict=True)]
    return mean, lo, hi, int(est[-1]["walks"])


def optimize_progress(curves: list[list[tuple[float, int]]], path: Path,
                      title: str = "Best fitness found") -> Path:
    """Best fitness against seconds: one search as a step line; several (e.g. seeds) as their
    median and range."""
    import numpy as np

    fig, ax = plt.subplots(figsize=(7, 4), dpi=110)
    if len(curves) == 1:
        t, f = zip(*curves[0], strict=True) if curves[0] else ((), ())
        ax.step(t, f, where="post", lw=2)
    elif curves:
        end = max(c[-1][0] for c in curves if c)
        grid = np.linspace(0, end, 400)
        vals = np.array([[max([f for s, f in c if s <= g], default=np.nan) for g in grid]
                         for c in curves])
        ax.fill_between(grid, np.nanmin(vals, axis=0), np.nanmax(vals, axis=0), step="post",
                        alpha=0.3, label=f"range over {len(curves)} seeds")
        ax.step(grid, np.nanmedian(vals, axis=0), where="post", lw=2, label="median")
        ax.legend(fontsize=8, loc="lower right")
    ax.set_xlabel("seconds")
    ax.set_ylabel("best coverage fitness (3R + c)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def camera_error_map(error_map: dict, path: Path, markers=(),
                     title: str = "Expected position error of the camera") -> Path:
    """The position error a camera calibration expects over the area (its
    ``pose_error_map``: cm on a grid, None where the robot's marker is out of view), with
    the floor markers (x, y, size) as squares."""
    import numpy as np
    from matplotlib.patches import Rectangle

    xs, ys = np.asarray(error_map["x_cm"]), np.asarray(error_map["y_cm"])
    z = np.array([[np.nan if v is None else v for v in row] for row in error_map["error_cm"]],
                 dtype=np.float64)
    fig, ax = plt.subplots(figsize=(4.6, 6.2), dpi=110)
    ax.set_facecolor("0.85")  # out of view
    dx = xs[1] - xs[0] if len(xs) > 1 else 1.0
    dy = ys[1] - ys[0] if len(ys) > 1 else 1.0
    top = max(float(np.nanmax(z)) if np.isfinite(z).any() else 1.0, 0.5)
    mesh = ax.pcolormesh(np.append(xs - dx / 2, xs[-1] + dx / 2),
                         np.append(ys - dy / 2, ys[-1] + dy / 2), np.ma.masked_invalid(z),
                         cmap="viridis", vmin=0, vmax=top, shading="flat")
    fig.colorbar(mesh, ax=ax, label="expected position error (cm, RMS)")
    for x, y, size in markers:
        ax.add_patch(Rectangle((x - size / 2, y - size / 2), size, size, fc="k", ec="w", lw=0.5))
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    sub = (f"median {error_map['median_cm']} cm, max {error_map['max_cm']} cm; marker "
           f"{error_map['marker_height_cm']:g} cm up" if error_map.get("median_cm") is not None
           else "the marker is out of view everywhere")
    if error_map.get("unseen"):
        sub += f"; grey: out of view ({error_map['unseen']} points)"
    ax.set_title(_wrapped(f"{title}\n{sub}", 40), fontsize=9)
    return _save(fig, path)
