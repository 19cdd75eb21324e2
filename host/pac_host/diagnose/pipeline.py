"""The diagnosis from end to end: split, noise floor, where, which effect, how far it shrinks.

1. Split the runs by whole run (seeded) into fitting and held-out runs, unless a held-out file
   is given. Nothing about the held-out runs is used to fit: the noise floor and every
   parameter come from the fitting runs alone.
2. Noise floor from repeated identical steps of the fitting runs (:mod:`.noise`); whiteners for
   both sets (:mod:`.likelihood`).
3. Where: one-step body-frame residuals of the model on all runs, grouped (:mod:`.residuals`).
4. Which effect: forward selection (:mod:`.select`).
5. How far it shrinks: held-out step rms and rollout end-pose error before and after, with a
   bootstrap interval over held-out runs of the rollout shrink.
6. Whether the runs can tell the effects apart at all (:func:`identifiability`): each effect's
   whitened signature at a moderate magnitude on the fitting runs; an effect whose signature
   is too weak cannot be seen, and two effects look alike when what tells their signatures
   apart is too weak.
   A selected effect that looks alike another is reported with it ("consistent with A or B")
   and the diagnosis is marked not informative: the runs cannot tell the two apart.
7. Beyond the library: the residual's shape (:mod:`.shape`) on all runs; a shape noise cannot
   make means ``partly_unexplained``, and then candidate terms outside the library are fitted
   and judged on the held-out runs (:mod:`.propose`), naming the kind of what is missing, or,
   when several fit about equally or none explains most of it, saying so with their evidence
   and the run that would separate them (:mod:`.rank`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.diagnose import stats
from pac_host.diagnose.fit import Problem
from pac_host.diagnose.fitted_rows import fitted_rows_problems
from pac_host.diagnose.likelihood import whitener
from pac_host.diagnose.noise import NoiseFloor, estimate_noise
from pac_host.diagnose.propose import family_tests, propose
from pac_host.diagnose.rank import (
    MIN_SHARE,
    Candidate,
    family_predictor,
    mixture_predictor,
    rank,
    separating_run,
    where_summary,
)
from pac_host.diagnose.residuals import (
    Batch,
    batch_of,
    coverage_gap,
    end_errors,
    rollout_poses,
    step_residuals,
    where_report,
)
from pac_host.diagnose.runs import Run
from pac_host.diagnose.select import (
    ALPHA,
    Selection,
    forward_select,
    holdout_figures,
    library_names,
)
from pac_host.diagnose.shape import flagged, shape_tests
from pac_host.errors import InputError
from pac_host.model.effects import EFFECT_SPECS, Effect
from pac_host.model.table import GaitTable

# moderate magnitudes at which an effect should be visible (the benchmark's ranges)
REFERENCE = {
    "turn_shift": [Effect("turn_shift", {"k": 1})],
    "turn_scale": [Effect("turn_scale", {"c": 1.1})],
    "stride_scale": [Effect("stride_scale", {"a": 1.1})],
    "yaw_bias": [Effect("yaw_bias", {"delta": 0.5})],
    "lateral_slip": [Effect("lateral_slip", {"gamma": 0.05})],
    "transition": [Effect("transition", {"alpha": 0.3})],
    "battery_sag": [Effect("battery_sag", {"beta": 0.0002})],
    "floor_slope": [Effect("floor_slope", {"s": 0.3, "theta": 0.0}),
                    Effect("floor_slope", {"s": 0.3, "theta": 90.0})],
}


def reference(name: str) -> list[Effect]:
    """Moderate magnitudes of an effect: the built-in table, or a user effect's own."""
    if name in REFERENCE:
        return REFERENCE[name]
    ref = EFFECT_SPECS[name].reference
    return [Effect(name, ref)] if ref else []


MIN_SIGNAL = 25.0  # whitened |signature|^2 (about a 5-sigma effect) for "visible"
MIN_FIT_STEPS = 60

# which new test runs would separate two effects that look alike on the runs given
SEPARATE = {
    frozenset({"turn_shift", "turn_scale"}): "runs that hold each turn strength, hardest turns "
    "included: a shift moves each strength to its neighbour's row, a scale stretches all",
    frozenset({"stride_scale", "battery_sag"}): "runs started at very different times since "
    "power-on: sag grows with time, a stride scale does not",
    frozenset({"turn_scale", "lateral_slip"}): "runs of straight and turning gait cycles side by "
    "side: slip adds lateral motion in proportion to the turn, scale also changes the turn",
    frozenset({"yaw_bias", "turn_scale"}): "straight runs and runs turning both ways: a bias "
    "turns the same way on every gait cycle, a scale follows the turn's sign",
    frozenset({"transition", "turn_scale"}): "turn cycles with long repeats of one gait cycle",
}
GENERIC_SEPARATE = ("runs with more variety: both turn directions, frequent and rare gait "
                    "changes, different headings and times since power-on")


@dataclass
class Diagnosis:
    table: GaitTable
    fit_ids: tuple[str, ...]
    hold_ids: tuple[str, ...]
    noise: NoiseFloor
    where: dict
    coverage: dict
    selection: Selection
    candidates: list[dict]
    holdout: dict
    identifiability: dict
    notes: list[str]
    example_paths: dict  # the held-out run with the largest gap: observed, model, corrected
    informative: bool  # False: runs too short or too few repeats for the verdict to carry weight
    unexplained: dict | None = None  # beyond the library: shape tests, kind, proposed term

    @property
    def selected(self) -> list[Effect]:
        return self.selection.selected

    @property
    def verdict(self) -> str:
        return self.selection.verdict

    def corrected_table(self) -> GaitTable:
        """The model with the selected effects added (what ``--write-model`` writes)."""
        return self.table.with_effects(tuple(self.table.effects) + tuple(self.selected),
                                       name=self.table.name + "+diagnosed")


def split_runs(runs: Sequence[Run], fraction: float, rng: np.random.Generator
               ) -> tuple[list[Run], list[Run]]:
    """Split whole runs at random: (fitting, held-out), at least one of each."""
    if not 0.0 < fraction < 1.0:
        raise InputError(f"--holdout-fraction must be between 0 and 1, got {fraction}")
    if len(runs) < 2:
        raise InputError(
            f"runs: too few runs to hold any out (got {len(runs)}, need at least 2; "
            "or give --holdout RUNS2.jsonl)"
        )
    k = min(max(1, round(fraction * len(runs))), len(runs) - 1)
    order = rng.permutation(len(runs))
    hold = set(order[:k].tolist())
    return ([r for i, r in enumerate(runs) if i not in hold],
            [r for i, r in enumerate(runs) if i in hold])


def _problem(table: GaitTable, batch: Batch, noise: NoiseFloor) -> Problem:
    return Problem(table.rows, tuple(table.effects), batch, whitener(batch, noise))


def _problems(table: GaitTable, fit_b: Batch, hold_b: Batch
              ) -> tuple[NoiseFloor, Problem, Problem]:
    """The noise floor, estimated on the fitting runs, and the fitting and held-out problems
    whitened with it."""
    noise = estimate_noise(fit_b, step_residuals(table.rows, fit_b, tuple(table.effects)))
    return noise, _problem(table, fit_b, noise), _problem(table, hold_b, noise)


def select_effects(table: GaitTable, fit_runs: Sequence[Run], hold_runs: Sequence[Run],
                   library: Sequence[str] | None = None, rows_fitted: bool = False
                   ) -> tuple[Effect, ...]:
    """The effects :func:`diagnose` would select, without its report: the forward selection
    on the fitting runs judged on the held-out ones, nothing else (no bootstrap intervals,
    shape tests or proposals). For callers that only act on the selection, e.g. the model
    correction of every punctuation, where the whole report took seconds. ``rows_fitted``:
    the rows the fitting runs use were fitted to their steps, so they are fitted beside each
    effect and their estimation error is counted in the held-out runs' noise
    (:mod:`~pac_host.diagnose.fitted_rows`)."""
    _, fit_p, hold_p = _problems(table, batch_of(fit_runs), batch_of(hold_runs))
    if rows_fitted:
        fit_p, hold_p = fitted_rows_problems(fit_p, hold_p)
    return tuple(forward_select(fit_p, hold_p, library).selected)


def diagnose(
    table: GaitTable,
    fit_runs: Sequence[Run],
    hold_runs: Sequence[Run],
    rng: np.random.Generator,
    library: Sequence[str] | None = None,
    order: Sequence[str] | None = None,
) -> Diagnosis:
    """Diagnose the gap between ``table`` and the observed runs (see the module docstring).

    ``order``: the run ids in the order they were recorded (default: the fitting runs, then
    the held-out runs, each as given), for changes that happen between runs.
    """
    ids = [r.run_id for r in fit_runs] + [r.run_id for r in hold_runs]
    if len(set(ids)) != len(ids):
        dup = next(i for i in ids if ids.count(i) > 1)
        raise InputError(f"run {dup!r}: run_id appears in both the fitting and held-out runs")
    if library is not None:
        unknown = [n for n in library if n not in EFFECT_SPECS]
        if unknown:
            raise InputError(f"library: unknown effect {unknown[0]!r} "
                             f"(known: {', '.join(EFFECT_SPECS)})")
    fit_b, hold_b = batch_of(fit_runs), batch_of(hold_runs)
    base = tuple(table.effects)
    noise, fit_p, hold_p = _problems(table, fit_b, hold_b)
    all_b = batch_of(list(fit_runs) + list(hold_runs))
    where = where_report(all_b, step_residuals(table.rows, all_b, base))
    ends = end_errors(table.rows, all_b, base)
    where["rollout_end_cm"] = {
        "mean": round(float(ends.mean()), 3), "median": round(float(np.median(ends)), 3),
        "max": round(float(ends.max()), 3),
        "per_run": {rid: round(float(e), 3) for rid, e in zip(all_b.run_ids, ends, strict=True)}}
    coverage = coverage_gap(table.rows, all_b, base)
    sel = forward_select(fit_p, hold_p, library)
    rms0, end0 = holdout_figures(hold_p, [])
    candidates = [_candidate_json(c, hold_p, rms0, end0) for c in sel.candidates]
    rms1, end1 = holdout_figures(hold_p, sel.selected)
    shrink = 1.0 - end1.sum() / end0.sum() if end0.sum() > 0 else 0.0
    lo, hi = stats.bootstrap_ratio_ci(end1, end0, rng)
    holdout = {
        "runs": len(hold_runs),
        "rollout_cm_before": round(float(end0.mean()), 3),
        "rollout_cm_after": round(float(end1.mean()), 3),
        "shrink": round(float(shrink), 4),
        "shrink_ci": [round(lo, 4), round(hi, 4)],
        "step_rms_before": {k: round(v, 4) for k, v in rms0.items()},
        "step_rms_after": {k: round(v, 4) for k, v in rms1.items()},
        "step_rms_shrink": {k: round(1 - rms1[k] / rms0[k], 4) if rms0[k] > 0 else 0.0
                            for k in rms0},
        "per_run": [{"run_id": rid, "rollout_cm_before": round(float(a), 3),
                     "rollout_cm_after": round(float(b), 3)}
                    for rid, a, b in zip(hold_b.run_ids, end0, end1, strict=True)],
        "structure_test": sel.structure,
        # where the held-out residual left by the selected effects lies
        "where_remaining": where_report(
            hold_b, step_residuals(table.rows, hold_b, base + tuple(sel.selected))),
    }
    ident = identifiability(fit_p, library_names(library, base))
    # an effect whose signature on these runs is nearly that of another is named with it
    confounded = any(sel.alike.get(e.name) for e in sel.selected)
    for e in sel.selected:
        for pair in ident["alike"]:
            if e.name in (pair["a"], pair["b"]):
                other = pair["b"] if pair["a"] == e.name else pair["a"]
                if other not in {x.name for x in sel.selected}:
                    confounded = True
                    sel.alike.setdefault(e.name, [])
                    if other not in sel.alike[e.name]:
                        sel.alike[e.name].append(other)
    # strong on the fitting runs, but the held-out runs exercise it far less (under a tenth of
    # what their share of the data would give): they cannot confirm it, so inconclusive
    share = hold_p.n_obs / fit_p.n_obs
    untestable = [c.name for c in sel.last_round
                  if c.p_lr < ALPHA and c.lr > MIN_SIGNAL and c.name not in sel_names(sel)
                  and c.signal_holdout < 0.1 * c.lr * share]
    notes = _notes(noise, fit_b, ident, sel)
    notes += [f"{n} fits the fitting runs (likelihood-ratio p < {ALPHA}) but the held-out runs "
              "cannot show it; hold out runs that exercise it, or more runs"
              for n in untestable]
    worst = int(np.argmax(end0))
    n = int(hold_b.lengths[worst])
    unexplained = beyond_library(table, fit_b, hold_b, all_b, noise, sel, order, fit_p, hold_p)
    paths = {"run_id": hold_b.run_ids[worst], "observed": hold_b.poses[worst, : n + 1],
             "model": rollout_poses(table.rows, hold_b, base)[worst, : n + 1],
             "corrected": rollout_poses(table.rows, hold_b,
                                        base + tuple(sel.selected))[worst, : n + 1]}
    return Diagnosis(table, tuple(r.run_id for r in fit_runs), tuple(r.run_id for r in hold_runs),
                     noise, where, coverage, sel, candidates, holdout, ident, notes, paths,
                     fit_b.n_steps >= MIN_FIT_STEPS and noise.reliable and not confounded
                     and not untestable, unexplained)


MIX_MIN_GAIN = 25.0  # held-out nats a mixture of scales must gain over one Gaussian


def _chronology(b: Batch, order: Sequence[str]) -> np.ndarray:
    pos = {rid: k for k, rid in enumerate(order)}
    if any(rid not in pos for rid in b.run_ids):
        missing = next(rid for rid in b.run_ids if rid not in pos)
        raise InputError(f"run {missing!r}: not in the recorded order given")
    return np.array([pos[rid] for rid in b.run_ids], float) / max(len(order) - 1, 1)


def beyond_library(table: GaitTable, fit_b: Batch, hold_b: Batch, all_b: Batch,
                   noise: NoiseFloor, sel: Selection, order: Sequence[str] | None,
                   fit_p: Problem, hold_p: Problem) -> dict:
    """Shape tests on all runs; if the gap is partly unexplained, the proposal and its kind.

    Sets ``sel.verdict`` to ``partly_unexplained`` when a shape test fails."""
    order = list(order) if order is not None else list(fit_b.run_ids) + list(hold_b.run_ids)
    all_p = _problem(table, all_b, noise)
    tests = shape_tests(all_p, sel.selected, noise,
                        family_tests(all_p, sel.selected, _chronology(all_b, order)))
    flags = flagged(tests)
    if flags:
        sel.verdict = "partly_unexplained"
    out: dict = {"shape_tests": [t.to_json() for t in tests],
                 "flags": [t.name for t in flags], "kind": None, "description": None,
                 "proposal": None, "intermittent": None, "families": [], "kind_verdict": None,
                 "alike": [], "ranking": [], "separating_run": None, "where": None}
    if sel.verdict != "partly_unexplained":
        return out
    props, mix = propose(fit_p, hold_p, sel.selected, _chronology(fit_b, order),
                         _chronology(hold_b, order), noise)
    out["families"] = [{"family": q.family, "holdout_loglik_gain": round(q.holdout_gain / 2, 3),
                        "p_value": q.p_value, "shrink": round(q.shrink, 4)} for q in props]
    mix_runs = None if mix is None else mix.pop("run_gains")
    mix_end = None if mix is None else mix.pop("run_end_cm")
    out["intermittent"] = mix
    out["where"] = where_summary(all_b, step_residuals(table.rows, all_b, tuple(table.effects)
                                                      + tuple(sel.selected)), noise)
    cands = [Candidate(q.family, q.kind, q.description, q.run_gains / 2.0, q.shrink,
                       family_predictor(q, hold_p), q.to_json(), q.run_end_cm)
             for q in props if q.p_value < ALPHA and q.holdout_gain > 0]
    mix_ok = (mix is not None and mix["holdout_loglik_gain"] > MIX_MIN_GAIN
              and 0.03 <= mix["share"] <= 0.6
              and abs(mix["scale_major"] - mix["scale_minor"]) > 0.3)
    if mix_ok:
        cands.append(Candidate(
            "intermittent", "intermittent", mix["description"], np.asarray(mix_runs, float),
            mix["holdout"]["shrink"], mixture_predictor(mix, hold_p),
            {"family": "intermittent", "kind": "intermittent",
             "description": mix["description"],
             "terms": [{"term": "the move scaled by a two-component mixture",
                        "share": round(mix["share"], 4),
                        "scales": [round(mix["scale_major"], 4), round(mix["scale_minor"], 4)]}],
             "holdout": {"loglik_gain": round(mix["holdout_loglik_gain"], 3),
                         **mix["holdout"]}}, mix_end))
    w0 = hold_p.whitened(sel.selected)
    excess = (float(w0 @ w0) - hold_p.n_obs) / 2.0  # held-out nats above the noise floor
    out["holdout_excess_loglik"] = round(excess, 2)
    order_c, ranking, n_alike = rank(cands, excess)
    out["ranking"] = ranking
    if order_c:
        top = order_c[0]
        out["proposal"] = top.proposal
        acts = top.proposal.get("acts_most_on")
        if acts:  # the quantity the leading explanation changes most, against the noise
            out["where"]["component"] = acts
        share = ranking[0]["share_of_excess"]
        alike = [top] + [c for c, r in zip(order_c[1:], ranking[1:], strict=True)
                         if r["alike_leader"]]
        out["alike"] = [c.kind for c in alike]
        if n_alike > 1:
            out["kind"] = out["kind_verdict"] = "ambiguous"
            out["description"] = ("one of these fits about as well as the others on the "
                                  "held-out runs: " + "; or ".join(c.description for c in alike))
        elif share is not None and share < MIN_SHARE:
            out["kind"] = out["kind_verdict"] = "uncertain"
            out["description"] = (f"no candidate explains most of the gap: the best, "
                                  f"{top.description}, takes {share:.0%} of what the held-out "
                                  "runs leave above the noise floor; the cause may be of a kind "
                                  "not among the candidates (see where)")
        else:
            out["kind"], out["description"] = top.kind, top.description
            out["kind_verdict"] = "named"
        if n_alike > 1 or out["kind_verdict"] == "uncertain":
            out["separating_run"] = separating_run(alike if n_alike > 1 else order_c[:2],
                                                   hold_b, noise)
    elif flags:  # the shape is not noise's, but no term holds on the held-out runs
        out["kind"] = out["kind_verdict"] = "uncertain"
        out["alike"] = list(dict.fromkeys(f.kind for f in flags))
        out["description"] = ("the residual's shape is not noise's ("
                              + "; ".join(f.description for f in flags[:3])
                              + "), but no candidate term holds on the held-out runs")
    else:
        out["kind"] = "library_like"
        out["kind_verdict"] = "library_like"
        out["description"] = ("structure of the library's kind remains (by gait cycle, "
                              "gait change, time or world drift); see where_remaining")
    return out


def sel_names(sel: Selection) -> set[str]:
    return {e.name for e in sel.selected}


def _candidate_json(c, hold_p: Problem, rms0: dict, end0: np.ndarray) -> dict:
    rms1, end1 = holdout_figures(hold_p, c.fit.effects)
    shrink = 1.0 - end1.sum() / end0.sum() if end0.sum() > 0 else 0.0
    step_before = float(np.sqrt(np.mean([v**2 for v in rms0.values()])))
    step_after = float(np.sqrt(np.mean([v**2 for v in rms1.values()])))
    return {
        "effect": c.name,
        "params": {k: round(float(v), 6) for k, v in c.effect.params.items()},
        "fit": {"intervals_95": c.fit.intervals.get(c.name, {}),
                "lr_statistic": round(c.lr, 3), "p_lr": c.p_lr,
                "whitened_ssr": round(c.fit.ssr, 3), "n_obs": c.fit.n_obs,
                "sigma2": round(c.fit.sigma2, 4)},
        "holdout": {"step_rms_before": round(step_before, 4),
                    "step_rms_after": round(step_after, 4),
                    "step_rms_by_component_after": {k: round(v, 4) for k, v in rms1.items()},
                    "rollout_cm_before": round(float(end0.mean()), 3),
                    "rollout_cm_after": round(float(end1.mean()), 3),
                    "shrink": round(float(shrink), 4),
                    "loglik_gain": round(c.gain / 2.0, 3), "z": round(c.z, 3),
                    "signal": round(c.signal_holdout, 3)},
        "p_value": c.p_holdout,
        "delta_bic": round(c.delta_bic, 3),
    }


def identifiability(prob: Problem, names: Sequence[str]) -> dict:
    """Per effect, how strongly a moderate magnitude shows in the fitting runs (whitened
    |signature|^2, about the likelihood-ratio statistic it would give), and which pairs look
    alike: the part of the weaker signature outside the other's span (|d|^2 (1 - rho^2), rho
    the largest canonical correlation) is below :data:`MIN_SIGNAL`, so even at a moderate
    magnitude the runs could not tell the two apart."""
    w0 = prob.whitened([])
    bases, strength = {}, {}
    names = [n for n in names if reference(n)]  # a user effect may give no reference
    for n in names:
        cols = np.stack([w0 - prob.whitened([e]) for e in reference(n)], axis=1)
        strength[n] = float((cols**2).sum(axis=0).min())
        q, r = np.linalg.qr(cols)
        keep = np.abs(np.diag(r)) > 1e-9 * max(np.abs(np.diag(r)).max(), 1e-300)
        bases[n] = q[:, keep]
    pairs = []  # among the effects these runs can show at all
    ns = [n for n in names if bases[n].shape[1] and strength[n] >= MIN_SIGNAL]
    for i, a in enumerate(ns):
        for b in ns[i + 1 :]:
            corr = min(float(np.linalg.svd(bases[a].T @ bases[b], compute_uv=False).max()), 1.0)
            # what tells them apart: the part of a signature outside the other's span
            apart = min(strength[a], strength[b]) * (1.0 - corr**2)
            if apart < MIN_SIGNAL:
                pairs.append({"a": a, "b": b, "correlation": round(corr, 4),
                              "signal_apart": round(apart, 1),
                              "runs_that_separate": SEPARATE.get(frozenset({a, b}),
                                                                 GENERIC_SEPARATE)})
    return {"signal_at_reference": {n: round(v, 1) for n, v in strength.items()},
            "reference": {n: [str(e) for e in reference(n)] for n in names},
            "invisible": [n for n, v in strength.items() if v < MIN_SIGNAL],
            "alike": pairs}


def _notes(noise: NoiseFloor, fit_b: Batch, ident: dict, sel: Selection) -> list[str]:
    notes = []
    if fit_b.n_steps < MIN_FIT_STEPS:
        notes.append(f"only {fit_b.n_steps} fitting steps (< {MIN_FIT_STEPS}): too short to "
                     "tell effects apart reliably; record longer runs")
    if not noise.reliable:
        notes.append(f"noise floor from only {noise.n_used} repeated identical steps "
                     f"({noise.method}); turn cycles with genes repeated 3+ times fix this")
    if ident["invisible"]:
        notes.append("these runs cannot show (at moderate magnitude): "
                     + ", ".join(ident["invisible"]))
    for p in ident["alike"]:
        if p["a"] in {e.name for e in sel.selected} or p["b"] in {e.name for e in sel.selected}:
            notes.append(f"{p['a']} and {p['b']} look alike on these runs "
                         f"(correlation {p['correlation']}); to separate: "
                         f"{p['runs_that_separate']}")
    for name, others in sel.alike.items():
        if others:
            notes.append(f"held-out data also consistent with {', '.join(others)} instead of "
                         f"{name}")
    return notes

