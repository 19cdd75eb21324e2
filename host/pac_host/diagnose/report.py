"""The diagnosis report: pac-diagnosis/1 JSON, a short terminal summary, and PNG plots.

Findings are worded "consistent with" an effect: the method shows that modelling the effect
removes the gap on runs it did not fit, not that the robot's mechanism is that effect.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from pac_host.diagnose.pipeline import Diagnosis
from pac_host.diagnose.residuals import top_places
from pac_host.files import make_dirs, write_atomic, write_atomic_with
from pac_host.model.table import COMPONENTS

FORMAT = "pac-diagnosis/1"

VERDICT_TEXT = {
    "no_significant_gap": "no significant unmodelled effect: the residual is at the noise floor",
    "explained": "the gap is consistent with the selected effects; what remains is noise",
    "partly_unexplained": "the gap is partly unexplained: structure remains above the noise "
    "floor that no effect of the library accounts for",
}


def _clean(v):
    """JSON-safe: numpy scalars to Python, non-finite floats to None."""
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_clean(x) for x in v]
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        v = float(v)
        return v if math.isfinite(v) else None
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def to_json(d: Diagnosis, meta: dict | None = None) -> dict:
    """The pac-diagnosis/1 document."""
    sel = d.selection
    doc = {
        "format": FORMAT,
        **(meta or {}),
        "model": d.table.name,
        "runs": {"fitting": list(d.fit_ids), "held_out": list(d.hold_ids)},
        "noise_floor": d.noise.to_json(),
        "where": {**d.where, "coverage": {k: v for k, v in d.coverage.items()
                                          if k != "per_run"},
                  "coverage_per_run": d.coverage["per_run"]},
        "candidates": d.candidates,
        "selected": [e.name for e in d.selected],
        "selected_effects": [e.to_json() for e in d.selected],
        "consistent_with": [
            {"effect": e.name, "params": e.params,
             "intervals_95": sel.intervals(e.name),
             "alike": sel.alike.get(e.name, [])} for e in d.selected],
        "selection_steps": sel.steps,
        "verdict": d.verdict,
        "verdict_text": VERDICT_TEXT[d.verdict],
        "informative": d.informative,
        "holdout": d.holdout,
        "identifiability": d.identifiability,
        "unexplained": d.unexplained,
        "notes": d.notes,
    }
    return _clean(doc)


def write_json(doc: dict, path: str | Path) -> None:
    write_atomic(path, json.dumps(doc, indent=1) + "\n")


def summary(d: Diagnosis) -> list[str]:
    """The terminal report: verdict, top places of the gap, selected effects, the shrink."""
    h = d.holdout
    lines = [f"verdict: {d.verdict} ({VERDICT_TEXT[d.verdict]})"]
    if not d.informative:
        lines.append("caution: these runs are too short or too uniform to tell effects apart "
                     "reliably (see the notes below); record more varied runs")
    lines += [
             f"runs: {len(d.fit_ids)} fitting, {len(d.hold_ids)} held out; noise floor "
             f"{d.noise.pos_cm:.2f} cm, {d.noise.heading_deg:.2f} deg"]
    comp = d.where["by_component"]
    lines.append("step residual rms (all runs, model as given): "
                 + ", ".join(f"{c} {comp[c]:.2f}" for c in COMPONENTS)
                 + f"; rollout end error {d.where['rollout_end_cm']['mean']:.1f} cm")
    places = top_places(d.where)
    if places:
        lines.append("where the gap is largest:")
        lines += [f"  {p}" for p in places]
    if d.selected:
        lines.append("partly consistent with:" if d.verdict == "partly_unexplained"
                     else "consistent with:")
        for e in d.selected:
            ci = d.selection.intervals(e.name)
            params = ", ".join(
                f"{k}={v:.4g}" + (f" [{ci[k][0]:.4g}, {ci[k][1]:.4g}]" if k in ci else "")
                for k, v in e.params.items())
            alike = d.selection.alike.get(e.name) or []
            extra = f" (or: {', '.join(alike)})" if alike else ""
            lines.append(f"  {e.name}: {params}{extra}")
    else:
        best = d.candidates[0] if d.candidates else None
        if best:
            lines.append(f"best candidate {best['effect']} not significant "
                         f"(held-out p={best['p_value']:.2g}, dBIC={best['delta_bic']:.1f})")
    if d.verdict == "partly_unexplained":
        u = d.unexplained or {}
        if u.get("flags"):
            lines.append("the residual's shape is not noise's: " + ", ".join(u["flags"]))
        lines += _where_lines(u.get("where"))
        lines += _kind_lines(u)
        prop = u.get("proposal")
        if prop:
            ph = prop["holdout"]
            with_lib = prop.get("with_library_effects")
            lines.append(
                ("leading " if u.get("kind_verdict") != "named" else "")
                + f"proposed term ({prop['family']}, outside the library"
                + (f", with {', '.join(with_lib)}" if with_lib else "") + "): "
                + "; ".join(f"{t['term']} x {t['coefficient']:.4g}" if "coefficient" in t
                            else t["term"] for t in prop["terms"][:4])
                + (" ..." if len(prop["terms"]) > 4 else ""))
            lines.append(f"  held-out: rollout end error {ph['rollout_cm_model']:.1f} (model) "
                         f"-> {ph['rollout_cm_after']:.1f} cm, shrink {ph['shrink']:.2f}, "
                         f"log-likelihood gain {ph['loglik_gain']:.1f}"
                         + (f", p {ph['p_value']:.2g}" if "p_value" in ph else ""))
        rest = top_places(d.holdout["where_remaining"])
        if rest:
            lines.append("what remains unexplained (held-out runs):")
            lines += [f"  {p}" for p in rest]
    lines.append(
        f"held-out rollout end error {h['rollout_cm_before']:.1f} -> {h['rollout_cm_after']:.1f}"
        f" cm, shrink {100 * h['shrink']:.0f}% (95% CI {100 * h['shrink_ci'][0]:.0f}.."
        f"{100 * h['shrink_ci'][1]:.0f}%)")
    lines += [f"note: {n}" for n in d.notes]
    return lines


def _where_lines(w: dict | None) -> list[str]:
    """Where the residual the library leaves lies, with the numbers to judge it."""
    if not w:
        return []
    ratio = w["rms_over_noise"]
    out = [f"where the gap lies (model and selected effects, all runs): mostly {w['component']};"
           " residual rms against the noise of one move: "
           + ", ".join(f"{c} {ratio[c]:.2f}x" for c in COMPONENTS)]
    rows = list(w.get("contexts") or [])
    ch = w.get("change_vs_repeat")
    if ch and all(r["context"] != ch["context"] for r in rows):
        rows.append(ch)
    out += [f"  {r['text']}" for r in rows]
    return out


def _kind_lines(u: dict) -> list[str]:
    """The kind of what is missing: named, or the candidates that fit about equally with
    their evidence and the run that would separate them, or uncertain."""
    verdict = u.get("kind_verdict")
    ranking = u.get("ranking") or []
    if verdict not in ("ambiguous", "uncertain", "named") or not ranking:
        return [f"what is missing ({u['kind']}): {u['description']}"] if u.get("description") \
            else []
    top = ranking[0]
    if verdict == "named":
        out = [f"what is missing ({u['kind']}): {u['description']}", "  " + _evidence(top)]
        if len(ranking) > 1:
            r = ranking[1]
            lo, hi = r["behind_leader_interval_95"]
            out.append(f"  next best {r['kind']}: behind by {r['behind_leader']:.1f} "
                       f"[{lo:.1f}, {hi:.1f}] in log-likelihood" + _rollout_lead(r)
                       + " (paired over held-out runs)")
        return out
    shown = [r for r in ranking if r["rank"] == 1 or r.get("alike_leader")]
    if verdict == "ambiguous":
        out = ["kind of what is missing: ambiguous, one of these fits about as well as the "
               f"others on the held-out runs ({', '.join(r['kind'] for r in shown)}):"]
    else:
        shown = ranking[:3]
        out = [f"kind of what is missing: uncertain; {u['description']}"]
    for r in shown:
        out.append(f"  {r['rank']}. {r['kind']}: {r['description']}")
        out.append("     " + _evidence(r))
    sep = u.get("separating_run")
    if sep:
        out.append(f"a run that would tell them apart: {sep['run']} (their predictions differ "
                   f"by about {sep['separation_sigma']:.0f} noise standard deviations)")
        out += [f"  {p['kind']} predicts a mean move of F {p['mean_move'][0]:+.2f} cm, "
                f"T {p['mean_move'][1]:+.2f} cm, dH {p['mean_move'][2]:+.2f} deg per cycle"
                for p in sep["predictions"]]
    return out


def _rollout_lead(r: dict) -> str:
    if r.get("rollout_behind_leader_cm") is None:
        return ""
    lo, hi = r["rollout_behind_leader_interval_95"]
    return (f", rollout end error {r['rollout_behind_leader_cm']:+.1f} cm [{lo:+.1f}, {hi:+.1f}] "
            "against the first")


def _evidence(r: dict) -> str:
    lo, hi = r["gain_interval_95"]
    text = (f"held-out log-likelihood gain {r['holdout_loglik_gain']:.1f} [{lo:.1f}, {hi:.1f}] "
            "(95%, over held-out runs)")
    if r.get("behind_leader") is not None:
        blo, bhi = r["behind_leader_interval_95"]
        text += f", behind the first by {r['behind_leader']:.1f} [{blo:.1f}, {bhi:.1f}]"
    text += _rollout_lead(r)
    if r.get("share_of_excess") is not None:
        text += f", {r['share_of_excess']:.0%} of the held-out excess over the noise"
    if r.get("shrink") is not None:
        text += f", rollout shrink {r['shrink']:.2f}"
    return text


def write_plots(d: Diagnosis, out_dir: str | Path) -> list[Path]:
    """PNG plots: residuals by gait cycle id, held-out rollout errors, candidate shrinks, and
    the held-out run with the largest gap: observed path, model replay, corrected replay."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    make_dirs(out)
    written = []
    rows = d.where["by_gait_cycle"]
    ids = [r["id"] for r in rows]
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for j, (ax, c) in enumerate(zip(axes, COMPONENTS, strict=True)):
        ax.bar(ids, [r["mean"][j] for r in rows], yerr=[1.96 * r["se"][j] for r in rows],
               color="tab:blue", capsize=2)
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylabel(f"{c} residual" + (" (deg)" if c == "dH" else " (cm)"))
    axes[-1].set_xlabel("gait cycle id")
    axes[0].set_title("one-step residual (observed - model) by gait cycle, 95% intervals")
    fig.tight_layout()
    written.append(_save(fig, out / "residuals_by_gait.png", plt))

    per = d.holdout["per_run"]
    fig, ax = plt.subplots(figsize=(7, 5))
    before = [r["rollout_cm_before"] for r in per]
    after = [r["rollout_cm_after"] for r in per]
    ax.scatter(before, after)
    top = max(before + after + [1.0])
    ax.plot([0, top], [0, top], "k--", lw=0.8, label="no change")
    ax.set_xlabel("held-out rollout end error, model as given (cm)")
    ax.set_ylabel("with selected effects (cm)")
    ax.set_title(f"held-out runs: shrink {100 * d.holdout['shrink']:.0f}%")
    ax.legend()
    fig.tight_layout()
    written.append(_save(fig, out / "holdout_rollout.png", plt))

    fig, ax = plt.subplots(figsize=(8, 4))
    names = [c["effect"] for c in d.candidates]
    ax.bar(names, [100 * c["holdout"]["shrink"] for c in d.candidates],
           color=["tab:green" if n in {e.name for e in d.selected} else "tab:gray"
                  for n in names])
    ax.set_ylabel("held-out rollout shrink alone (%)")
    ax.set_title("candidate effects (green: selected)")
    ax.tick_params(axis="x", rotation=30)
    fig.tight_layout()
    written.append(_save(fig, out / "candidates.png", plt))

    ex = d.example_paths
    fig, ax = plt.subplots(figsize=(6, 6))
    for key, style in (("observed", "k.-"), ("model", "r-"), ("corrected", "g-")):
        p = ex[key]
        ax.plot(p[:, 0], p[:, 1], style, lw=1, ms=3, label=key)
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.set_title(f"held-out run {ex['run_id']}: largest gap")
    ax.legend()
    fig.tight_layout()
    written.append(_save(fig, out / "worst_holdout_path.png", plt))
    return written


def _save(fig, path: Path, plt) -> Path:
    """The figure written whole (a failure is one line naming it; no half PNG stays)."""
    try:
        write_atomic_with(path, lambda f: fig.savefig(f, format="png", dpi=100))
    finally:
        plt.close(fig)
    return path
