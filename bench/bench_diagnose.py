"""Blind benchmark of `pac-host diagnose`: recover effects withheld from the method.

Each case draws a true table (the measured one, or a perturbed one for half the cases), an
effect or a pair of effects with parameters from the stated moderate ranges
(``pac_host.diagnose.synth.MODERATE``), 40 turn cycles of the kind a PAL session tests
(a short CGA run and the paper's perturbations), runs each for 60 gait cycles in the world
(the effects code the emulator uses) with tracker noise, holds out 30% of the runs, and runs the
diagnosis without telling it the effect. Categories:

- single: one effect in the library; scores top-1 (first selected effect is the true one),
  exact (selected set is exactly it), parameter error, held-out rollout shrink;
- pair: two effects; recall of both;
- null: no effect; a false positive is any selected effect or a verdict other than
  no_significant_gap;
- withheld: one effect, removed from the library; scores how often the verdict is
  partly_unexplained rather than a confident wrong name;
- single_high_noise: singles with three times the tracker noise (no target);
- table_error: no effect, but the model is the measured table while the robot is a
  re-measured one (every entry off by 0.3 cm / 0.5 deg): a gap no effect explains;
- null_step_noise / single_step_noise: the robot also varies by itself from step to step
  (0.3 cm on F and T, 0.6 deg on dH per gait cycle), which the noise floor must absorb;
- weak_short: singles at a quarter of the moderate magnitude on 12 runs of 30 gait cycles with
  high noise: where the method runs out of data (no target; shows the failure modes);
- outside: a gap no effect of the library can cause (``pac_host.diagnose.synth.OUTSIDE``:
  intermittent stalls, a periodic heading wobble, a payload change between runs, a floor
  patch of higher friction, a heading-dependent pull, a warm-up after power-on; and a weak leg
  on turns of one side, backlash after a reversal of the turn direction, a battery sag of fixed
  length, a ramp in a band of the floor, a tether, a carpet's grain, a warm-up after every
  pause between runs), each at three magnitude
  levels, 3 cases each; scores the verdict (partly_unexplained, never explained), whether the
  where summary names the quantity and the context of the gap (:data:`WHERE_TRUTH`), the kind
  (named rightly, or honestly: ambiguous with the true kind among those named, or uncertain;
  else wrong) and the held-out shrink of the leading proposed term. ``python
  bench/bench_diagnose.py --outside [--quick]`` runs this part alone.
- clean: the calibration check, 50 effect-free cases (:data:`CLEAN_LENGTHS`: 24 runs of 20,
  64, 65, 80, 200 or 400 gait cycles, or of 40 to 79 mixed; the start pose given exactly or
  observed; one power-on session or sessions of 8 runs; tracker noise 0.3 cm / 0.5 deg,
  0.5 / 1 or 1 / 2; with or without step noise), from the true table; a false flag is any
  verdict other than no_significant_gap. Target: at most 1 of 50. ``python
  bench/bench_diagnose.py --clean [--out FILE]`` runs this part alone (JSON on stdout, and in
  FILE if given).

Shrink is 1 - (held-out rollout end error after) / (before); the excess shrink divides by the
part above the oracle's error (the true model's own error, tracker noise alone).

Usage: ``python bench/run.py --only diagnose [--quick]`` or ``make bench-diagnose``.
"""

from __future__ import annotations

import time

import numpy as np

from pac_host.diagnose import diagnose
from pac_host.diagnose.residuals import batch_of, end_errors
from pac_host.diagnose.synth import MODERATE, OUTSIDE, blind_case, moderate_effect
from pac_host.model.effects import BUILT_IN, EFFECT_SPECS, Effect
from pac_host.model.table import GaitTable, measured_table

NAMES = [n for n in EFFECT_SPECS if n in BUILT_IN]
NOISE = {"moderate": (0.5, 1.0), "high": (1.5, 3.0)}
SEED = 2024
KINDS = ("single", "pair", "null", "withheld", "single_high_noise", "table_error", "weak_short",
         "null_step_noise", "single_step_noise", "outside", "clean")
LEVELS = 3  # magnitude levels of each outside kind
STEP_NOISE = (0.3, 0.6)  # the robot's own step variability: cm on F and T, deg on dH
WEAK = 0.25  # weak_short cases: a quarter of a moderate magnitude ...
SHORT = (12, 30)  # ... on 12 runs of 30 gait cycles, with high tracker noise
# the calibration check: run lengths (0: 40 to 79 mixed), tracker noise (cm, deg)
CLEAN_LENGTHS = (20, 64, 65, 80, 200, 400, 0)
CLEAN_NOISE = ((0.3, 0.5), (0.5, 1.0), (1.0, 2.0))
CLEAN_RUNS = 24
CLEAN_CASES = 50


def _param_error(true, est) -> float:
    """Relative error of the estimate; floor_slope as the drift vector; turn_shift 0 or 1."""
    if est is None:
        return float("nan")
    if true.name == "turn_shift":
        return float(est.params["k"] != true.params["k"])
    if true.name == "floor_slope":
        def vec(e):
            th = np.radians(e.params["theta"])
            return e.params["s"] * np.array([np.sin(th), np.cos(th)])
        return float(np.linalg.norm(vec(est) - vec(true)) / true.params["s"])
    (k,) = true.params
    ref = true.params[k] - EFFECT_SPECS[true.name].params[0].neutral
    return float(abs(est.params[k] - true.params[k]) / abs(ref))


def _weaker(effect: Effect, f: float) -> Effect:
    """The effect moved towards neutral: parameter = neutral + f (parameter - neutral)."""
    if effect.name == "turn_shift":
        return effect
    if effect.name == "floor_slope":
        return Effect("floor_slope", {"s": f * effect.params["s"],
                                      "theta": effect.params["theta"]})
    (p,) = EFFECT_SPECS[effect.name].params
    return Effect(effect.name, {p.name: p.neutral + f * (effect.params[p.name] - p.neutral)})


def _case(kind: str, index: int, effects, noise, library=None, perturb=False,
          model_rows=None, size=(40, 60), step_noise=(0.0, 0.0), outside=None,
          design: dict | None = None) -> dict:
    rng = np.random.default_rng([SEED, KINDS.index(kind), index])
    world, truth = (None, None)
    if outside is not None:  # (name, level): a gap outside the library
        world, truth = OUTSIDE[outside[0]][1](rng, outside[1])
    extra = {}
    if design is not None:  # a clean case: run lengths, start pose, sessions
        extra = {"lengths": design["lengths"], "start_exact": design["start_exact"],
                 "runs_per_session": design["runs_per_session"]}
    rows, fit, hold = blind_case(rng, effects, n_runs=size[0], n_cycles=size[1],
                                 pos_noise_cm=noise[0], heading_noise_deg=noise[1],
                                 perturb_table=perturb, step_noise=step_noise, perturb=world,
                                 **extra)
    order = sorted(r.run_id for r in fit + hold)  # the runs in the order they were made
    t0 = time.perf_counter()
    d = diagnose(GaitTable(rows if model_rows is None else model_rows), fit, hold, rng, library,
                 order=order)
    wall = time.perf_counter() - t0
    # the oracle: the true model's own held-out rollout error (tracker noise alone)
    oracle = float(end_errors(rows, batch_of(hold), effects).mean())
    before, after = d.holdout["rollout_cm_before"], d.holdout["rollout_cm_after"]
    excess = (before - after) / (before - oracle) if before > oracle else float("nan")
    sel = [e.name for e in d.selected]
    return {"kind": kind, "true": [str(e) for e in effects],
            "true_names": [e.name for e in effects],
            "selected": sel, "selected_effects": [str(e) for e in d.selected],
            "verdict": d.verdict, "shrink": d.holdout["shrink"],
            "rollout_cm_before": d.holdout["rollout_cm_before"],
            "rollout_cm_after": d.holdout["rollout_cm_after"], "rollout_cm_oracle": oracle,
            "excess_shrink": excess,
            "param_error": [_param_error(t, next((e for e in d.selected if e.name == t.name),
                                                 None)) for t in effects],
            "alike": d.selection.alike, "informative": d.informative, "notes": d.notes,
            "wall_s": round(wall, 3), **_outside_figures(d, outside, truth),
            "design": None if design is None else {k: v for k, v in design.items()
                                                   if k != "lengths"}}


# where each outside kind's gap lies: the quantities it changes most and the context of the
# diagnosis' where summary it is confined to (None: everywhere, or between runs)
WHERE_TRUTH = {
    "stall": ({"F", "dH"}, None), "wobble": ({"dH"}, None), "payload": ({"F", "dH"}, None),
    "floor_patch": ({"F", "dH"}, "axis"), "heading_pull": ({"dH"}, ("heading",)),
    "warmup": ({"F", "dH"}, ("power_on",)), "weak_leg": ({"F"}, "side"),
    "backlash": ({"dH"}, ("turn_reversal", "change")), "sag_additive": ({"F"}, ("power_on",)),
    "slope_patch": ({"F", "T"}, "axis"), "tether": ({"F", "T"}, ("x", "y")),
    "carpet": ({"F"}, ("heading",)), "pause_warmup": ({"F", "dH"}, ("in_run",)),
}


def _where_named(name: str, truth: dict, where: dict | None) -> bool:
    """The where summary names the quantity the gap is on and, for a confined gap, the
    context it is confined to among its top contexts."""
    if not where:
        return False
    comps, ctx = WHERE_TRUTH[name]
    if where.get("component") not in comps:
        return False
    if ctx is None:
        return True
    listed = [c["context"] for c in where.get("contexts", [])]
    if ctx == "axis":
        return any(c.split("=")[0] == truth["axis"] for c in listed)
    if ctx == "side":  # the weak side, or the other one against it
        return "turn=right" in listed or "turn=left" in listed
    return any(c.split("=")[0] in ctx for c in listed)


def _outside_figures(d, outside, truth) -> dict:
    u = d.unexplained or {}
    prop = u.get("proposal") or {}
    hold = prop.get("holdout", {})
    top = (u.get("ranking") or [{}])[0]
    return {"outside": list(outside) if outside else None, "truth": truth,
            "true_kind": OUTSIDE[outside[0]][0] if outside else None,
            "kind_named": u.get("kind"), "description": u.get("description"),
            "kind_verdict": u.get("kind_verdict"), "alike": u.get("alike", []),
            "flags": u.get("flags", []),
            "where": u.get("where"),
            "where_named": _where_named(outside[0], truth, u.get("where")) if outside else None,
            "separating_run": (u.get("separating_run") or {}).get("run"),
            "leader_gain_interval": top.get("gain_interval_95"),
            "proposal_family": prop.get("family"),
            "proposal_shrink": hold.get("shrink"),
            "proposal_shrink_over_library": hold.get("shrink_over_library")}


def _kind_score(c: dict) -> str:
    """correct: the true kind named alone; ambiguous: several named, the true one among them;
    uncertain: the report says no candidate explains most of it; wrong: a kind named alone,
    wrongly, or several without the true one."""
    if c["kind_named"] == c["true_kind"]:
        return "correct"
    if c["kind_named"] == "ambiguous" and c["true_kind"] in c["alike"]:
        return "ambiguous"
    if c["kind_named"] == "uncertain":
        return "uncertain"
    return "ambiguous_without_truth" if c["kind_named"] == "ambiguous" else "wrong"


def outside_cases(quick: bool = False, names=None) -> list[dict]:
    """The outside-library cases: every kind of ``OUTSIDE`` at each magnitude level."""
    cases = []
    for name in names or OUTSIDE:
        for level in range(LEVELS) if not quick else (1,):
            for i in range(1 if quick else 3):
                index = 1000 * list(OUTSIDE).index(name) + 10 * level + i
                cases.append(_case("outside", index, [], NOISE["moderate"], perturb=i % 2 == 1,
                                   outside=(name, level)))
    return cases


def clean_design(i: int) -> dict:
    """The i-th clean case's design: the factors cycle with coprime-ish periods (7 lengths,
    2 starts, 2 session layouts, 3 tracker noises, 2 step noises), so 50 cases cover every
    length with each start, session layout and noise level."""
    length = CLEAN_LENGTHS[i % len(CLEAN_LENGTHS)]
    if length:
        lengths = [length] * CLEAN_RUNS
    else:  # mixed lengths, drawn from the case's own seed
        lengths = np.random.default_rng([SEED, 11, i]).integers(40, 80, CLEAN_RUNS).tolist()
    return {"length": length or "40-79", "lengths": lengths, "start_exact": i % 2 == 0,
            "runs_per_session": CLEAN_RUNS if (i // 2) % 2 == 0 else 8,
            "noise": CLEAN_NOISE[i % 3], "step_noise": STEP_NOISE if (i // 3) % 2 else (0.0, 0.0)}


def clean_cases(n: int = CLEAN_CASES) -> list[dict]:
    """The calibration check: ``n`` effect-free cases (:func:`clean_design`)."""
    out = []
    for i in range(n):
        dz = clean_design(i)
        out.append(_case("clean", i, [], dz["noise"], step_noise=dz["step_noise"], design=dz))
    return out


def clean_summary(cases: list[dict]) -> dict:
    """Flags on the clean cases: any verdict but no_significant_gap is a false flag."""
    false = [c for c in cases if c["selected"] or c["verdict"] != "no_significant_gap"]
    return {
        "what": f"effect-free, {CLEAN_RUNS} runs per case: lengths {CLEAN_LENGTHS} (0: 40-79 "
                "mixed), start exact or observed, one session or sessions of 8, tracker noise "
                f"{CLEAN_NOISE}, step noise 0 or {STEP_NOISE}",
        "cases": len(cases),
        "flagged": len(false),
        "partly_unexplained": sum(c["verdict"] == "partly_unexplained" for c in cases),
        "selected_any": sum(bool(c["selected"]) for c in cases),
        "false_flags": [{"design": c["design"], "verdict": c["verdict"],
                         "selected": c["selected_effects"], "flags": c["flags"]}
                        for c in false],
        "max_diagnosis_s": round(float(max((c["wall_s"] for c in cases), default=0.0)), 3),
    }


def _rng_effects(rng, names):
    return [moderate_effect(n, rng) for n in names]


def run(quick: bool = False) -> dict:
    n_single = 2 if quick else 15
    n_pair = 4 if quick else 30
    n_null = 6 if quick else 60
    n_withheld = 1 if quick else 5
    n_high = 0 if quick else 3
    n_table = 0 if quick else 10
    n_weak = 0 if quick else 5
    n_step = 1 if quick else 3
    pick = np.random.default_rng(SEED)
    cases = []
    for name in NAMES:
        for i in range(n_single):
            eff = [moderate_effect(name, np.random.default_rng([SEED, 1, NAMES.index(name), i]))]
            cases.append(_case("single", len(cases), eff, NOISE["moderate"], perturb=i % 2 == 1))
    for i in range(n_pair):
        a, b = pick.choice(len(NAMES), size=2, replace=False)
        eff = _rng_effects(np.random.default_rng([SEED, 2, i]), [NAMES[a], NAMES[b]])
        cases.append(_case("pair", len(cases), eff, NOISE["moderate"], perturb=i % 2 == 1))
    for i in range(n_null):
        cases.append(_case("null", len(cases), [], NOISE["moderate"], perturb=i % 2 == 1))
    for name in NAMES:
        for i in range(n_withheld):
            eff = [moderate_effect(name, np.random.default_rng([SEED, 3, NAMES.index(name), i]))]
            lib = [n for n in NAMES if n != name]
            cases.append(_case("withheld", len(cases), eff, NOISE["moderate"], lib,
                               perturb=i % 2 == 1))
    for name in NAMES:
        for i in range(n_high):
            eff = [moderate_effect(name, np.random.default_rng([SEED, 4, NAMES.index(name), i]))]
            cases.append(_case("single_high_noise", len(cases), eff, NOISE["high"],
                               perturb=i % 2 == 1))
    for _ in range(n_table):  # the model is the measured table, the robot a re-measured one
        cases.append(_case("table_error", len(cases), [], NOISE["moderate"], perturb=True,
                           model_rows=measured_table().rows))
    for name in NAMES:
        for i in range(n_weak):
            eff = [_weaker(moderate_effect(name, np.random.default_rng([SEED, 6, NAMES.index(name),
                                                                        i])), WEAK)]
            cases.append(_case("weak_short", len(cases), eff, NOISE["high"], size=SHORT,
                               perturb=i % 2 == 1))
    for i in range(n_step * 5):
        cases.append(_case("null_step_noise", len(cases), [], NOISE["moderate"],
                           perturb=i % 2 == 1, step_noise=STEP_NOISE))
    for name in NAMES:
        for i in range(n_step):
            eff = [moderate_effect(name, np.random.default_rng([SEED, 8, NAMES.index(name), i]))]
            cases.append(_case("single_step_noise", len(cases), eff, NOISE["moderate"],
                               perturb=i % 2 == 1, step_noise=STEP_NOISE))
    cases += outside_cases(quick)
    cases += clean_cases(len(CLEAN_LENGTHS) if quick else CLEAN_CASES)
    return summarize(cases, quick)


def _named_or_alike(c: dict) -> bool:
    """The true effect is named first, or named as alike to the first named effect."""
    if not c["selected"]:
        return False
    first = c["selected"][0]
    return first in c["true_names"] or bool(set(c["alike"].get(first, [])) & set(c["true_names"]))


def _confident_wrong(c: dict) -> bool:
    """A wrong effect named, without an alike hint or a caution, and the gap called explained."""
    return (bool(c["selected"]) and c["verdict"] == "explained" and c["informative"]
            and not _named_or_alike(c))


def _frac(xs) -> float:
    xs = list(xs)
    return round(float(np.mean(xs)), 4) if xs else float("nan")


def outside_summary(out: list[dict]) -> dict:
    """Scores of the outside-library cases: the verdict, where the gap is said to be, the
    kind (named, honestly ambiguous or uncertain, or wrong) and the proposals' shrink."""
    shrinks = [c["proposal_shrink"] if c["proposal_shrink"] is not None else 0.0 for c in out]
    over = [c["proposal_shrink_over_library"] if c["proposal_shrink_over_library"]
            is not None else 0.0 for c in out]
    score = [_kind_score(c) for c in out]

    def kinds(cs):
        sc = [_kind_score(c) for c in cs]
        return {k: _frac(v == k for v in sc) for k in
                ("correct", "ambiguous", "uncertain", "ambiguous_without_truth", "wrong")}
    return {
        "what": f"gaps no library effect causes, {len(OUTSIDE)} kinds x {LEVELS} magnitude "
                "levels",
        "cases": len(out),
        "partly_unexplained": _frac(c["verdict"] == "partly_unexplained" for c in out),
        "explained_with_wrong_effect": _frac(c["verdict"] == "explained" for c in out),
        "where_named": _frac(c["where_named"] for c in out),
        "kind_named": _frac(v == "correct" for v in score),
        "kind": kinds(out),
        "kind_correct_or_honest": _frac(v in ("correct", "ambiguous", "uncertain")
                                        for v in score),
        "confident_wrong": _frac(v == "wrong" for v in score),
        "separating_run_given_when_ambiguous": _frac(
            c["separating_run"] is not None for c in out if c["kind_named"] == "ambiguous"),
        "proposal_median_shrink": round(float(np.median(shrinks)), 4),
        "proposal_median_shrink_over_library": round(float(np.median(over)), 4),
        "proposal_made": _frac(c["proposal_family"] is not None for c in out),
        "per_kind": {name: {
            "kind": OUTSIDE[name][0],
            "partly_unexplained": _frac(c["verdict"] == "partly_unexplained" for c in cs),
            "where_named": _frac(c["where_named"] for c in cs),
            **kinds(cs),
            "median_proposal_shrink": round(float(np.median(
                [c["proposal_shrink"] or 0.0 for c in cs])), 4),
            "by_level": [{"level": lv, "kinds_named": [c["kind_named"] for c in cs
                                                        if c["outside"][1] == lv]}
                         for lv in range(LEVELS)]}
            for name in OUTSIDE
            if (cs := [c for c in out if c["outside"][0] == name])},
        "misses": [{"outside": c["outside"], "truth": c["truth"], "verdict": c["verdict"],
                    "selected": c["selected_effects"], "kind_named": c["kind_named"],
                    "alike": c["alike"], "description": c["description"],
                    "where": c["where"], "flags": c["flags"]}
                   for c, v in zip(out, score, strict=True)
                   if v in ("wrong", "ambiguous_without_truth") or not c["where_named"]
                   or c["verdict"] != "partly_unexplained"],
        "examples": [{"outside": c["outside"], "truth": c["truth"],
                      "kind_verdict": c["kind_verdict"], "description": c["description"],
                      "separating_run": c["separating_run"], "proposal": c["proposal_family"],
                      "shrink": c["proposal_shrink"]} for c in out[::LEVELS]],
    }


def summarize(cases: list[dict], quick: bool) -> dict:
    by = {k: [c for c in cases if c["kind"] == k] for k in KINDS}
    blind = [c for c in cases if c["kind"] != "clean"]  # timing as before the clean part
    singles = by["single"]
    per_effect = {}
    for name in NAMES:
        cs = [c for c in singles if c["true_names"] == [name]]
        if not cs:
            continue
        errs = [c["param_error"][0] for c in cs if c["selected"] and c["selected"][0] == name]
        per_effect[name] = {
            "cases": len(cs),
            "top1": _frac(c["selected"][:1] == [name] for c in cs),
            "exact": _frac(c["selected"] == [name] for c in cs),
            "median_param_error": round(float(np.median(errs)), 4) if errs else None,
            "median_shrink": round(float(np.median([c["shrink"] for c in cs])), 4),
            "median_rollout_cm": [round(float(np.median([c[k] for c in cs])), 2) for k in
                                  ("rollout_cm_before", "rollout_cm_after",
                                   "rollout_cm_oracle")],
            "median_excess_shrink": round(float(np.nanmedian([c["excess_shrink"] for c in cs])),
                                          4),
            "named_instead": sorted({c["selected"][0] for c in cs
                                     if c["selected"] and c["selected"][0] != name}),
        }
    withheld = {}
    for name in NAMES:
        cs = [c for c in by["withheld"] if c["true_names"] == [name]]
        if cs:
            withheld[name] = {"partly_unexplained": _frac(c["verdict"] == "partly_unexplained"
                                                          for c in cs),
                              "verdicts": [c["verdict"] for c in cs],
                              "named": [c["selected"] for c in cs]}
    high = by["single_high_noise"]
    top1 = _frac(c["selected"][:1] == c["true_names"] for c in singles)
    fp = _frac(bool(c["selected"]) or c["verdict"] != "no_significant_gap" for c in by["null"])
    shrinks = [c["shrink"] for c in singles]
    shrink_med = round(float(np.median(shrinks)), 4)
    res = {
        "quick": quick,
        "noise": {"moderate": {"pos_cm": NOISE["moderate"][0],
                               "heading_deg": NOISE["moderate"][1]},
                  "high": {"pos_cm": NOISE["high"][0], "heading_deg": NOISE["high"][1]}},
        "ranges": {n: MODERATE[n][1] for n in NAMES},
        "data": "40 runs x 60 gait cycles, 30% held out, CGA-like turn cycles",
        "cases": {k: len(v) for k, v in by.items()},
        "single_top1": top1,
        "single_informative": _frac(c["informative"] for c in singles),
        "single_exact": _frac(c["selected"] == c["true_names"] for c in singles),
        "single_median_shrink": shrink_med,
        "single_shrink_at_least_80pct": _frac(s >= 0.8 for s in shrinks),
        "per_effect": per_effect,
        "pair_recall": _frac(len(set(c["selected"]) & set(c["true_names"])) / 2
                             for c in by["pair"]),
        "pair_both_found": _frac(set(c["true_names"]) <= set(c["selected"]) for c in by["pair"]),
        "pair_misses": [{"true": c["true"], "selected": c["selected_effects"],
                         "verdict": c["verdict"]}
                        for c in by["pair"] if not set(c["true_names"]) <= set(c["selected"])],
        "null_false_positive": fp,
        "null_selected_any": _frac(bool(c["selected"]) for c in by["null"]),
        "withheld_partly_unexplained": _frac(c["verdict"] == "partly_unexplained"
                                             for c in by["withheld"]),
        "withheld_confident_wrong": _frac(c["verdict"] == "explained" for c in by["withheld"]),
        "withheld_per_effect": withheld,
        "high_noise_top1": _frac(c["selected"][:1] == c["true_names"] for c in high),
        "high_noise_median_shrink": (round(float(np.median([c["shrink"] for c in high])), 4)
                                     if high else None),
        "table_error_verdicts": {v: sum(c["verdict"] == v for c in by["table_error"])
                                 for v in ("no_significant_gap", "explained",
                                           "partly_unexplained")},
        "table_error_named": [c["selected"] for c in by["table_error"]],
        "single_median_excess_shrink": round(float(np.nanmedian(
            [c["excess_shrink"] for c in singles])), 4),
        "weak_short": {
            "what": f"{WEAK} x moderate magnitude, {SHORT[0]} runs x {SHORT[1]} cycles, high noise",
            "top1": _frac(c["selected"][:1] == c["true_names"] for c in by["weak_short"]),
            "verdicts": {v: sum(c["verdict"] == v for c in by["weak_short"])
                         for v in ("no_significant_gap", "explained", "partly_unexplained")},
            "named_or_alike": _frac(_named_or_alike(c) for c in by["weak_short"]),
            "confident_wrong": _frac(_confident_wrong(c) for c in by["weak_short"]),
            "cases": [{"true": c["true"], "selected": c["selected_effects"],
                       "verdict": c["verdict"], "alike": c["alike"],
                       "informative": c["informative"], "notes": c["notes"]}
                      for c in by["weak_short"]],
        },
        "step_noise": {"cm": STEP_NOISE[0], "deg": STEP_NOISE[1]},
        "step_noise_false_positive": _frac(bool(c["selected"])
                                           or c["verdict"] != "no_significant_gap"
                                           for c in by["null_step_noise"]),
        "step_noise_top1": _frac(c["selected"][:1] == c["true_names"]
                                 for c in by["single_step_noise"]),
        "step_noise_median_shrink": (round(float(np.median(
            [c["shrink"] for c in by["single_step_noise"]])), 4)
            if by["single_step_noise"] else None),
        "median_diagnosis_s": round(float(np.median([c["wall_s"] for c in blind])), 3),
        "max_diagnosis_s": round(float(np.max([c["wall_s"] for c in blind])), 3),
        "failures": [c for c in singles if c["selected"][:1] != c["true_names"]],
        "single_uninformative": [{"true": c["true"], "selected": c["selected_effects"],
                                  "notes": c["notes"]} for c in singles if not c["informative"]],
    }
    out = by["outside"]
    if out:
        res["outside"] = outside_summary(out)
    clean = clean_summary(by["clean"])
    res["clean"] = clean
    res["targets"] = {
        "clean_flagged": {"value": clean["flagged"], "of": clean["cases"],
                          "target": f"<= {max(1, clean['cases'] // CLEAN_CASES)}",
                          "met": clean["flagged"] <= max(1, clean["cases"] // CLEAN_CASES)},
        "single_top1": {"value": top1, "target": ">= 0.95", "met": top1 >= 0.95},
        "null_false_positive": {"value": fp, "target": "<= 0.05", "met": fp <= 0.05},
        "single_median_shrink": {"value": shrink_med, "target": ">= 0.80",
                                 "met": shrink_med >= 0.8},
    }
    if out:
        o = res["outside"]
        res["targets"].update({
            "outside_partly_unexplained": {"value": o["partly_unexplained"], "target": ">= 0.95",
                                           "met": o["partly_unexplained"] >= 0.95},
            "outside_explained_wrong": {"value": o["explained_with_wrong_effect"],
                                        "target": "<= 0.02",
                                        "met": o["explained_with_wrong_effect"] <= 0.02},
            "outside_where_named": {"value": o["where_named"], "target": ">= 0.90",
                                    "met": o["where_named"] >= 0.9},
            "outside_kind_correct_or_honest": {"value": o["kind_correct_or_honest"],
                                               "target": ">= 0.90",
                                               "met": o["kind_correct_or_honest"] >= 0.9},
            "outside_proposal_median_shrink": {"value": o["proposal_median_shrink"],
                                               "target": ">= 0.5",
                                               "met": o["proposal_median_shrink"] >= 0.5},
        })
    return res


if __name__ == "__main__":
    import json
    import sys

    if "--clean" in sys.argv:  # [--out FILE]: also write the summary there
        text = json.dumps(clean_summary(clean_cases()), indent=1)
        if "--out" in sys.argv:
            from pathlib import Path

            Path(sys.argv[sys.argv.index("--out") + 1]).write_text(text + "\n")
        print(text)
    elif "--outside" in sys.argv:
        print(json.dumps(outside_summary(outside_cases(quick="--quick" in sys.argv)), indent=1))
    else:
        print(json.dumps(run(quick="--quick" in sys.argv), indent=1))
