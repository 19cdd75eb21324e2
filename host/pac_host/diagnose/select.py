"""Which effect: forward selection among the library's effects, judged on held-out runs.

Round by round, every effect not yet selected is fitted jointly with those already selected on
the fitting runs (:mod:`.fit`) and scored on the held-out runs by the fall of their whitened
residual sum of squares (the held-out log-likelihood gain). The best candidate is accepted only
when all three hold:

- on the fitting runs, the likelihood-ratio statistic is significant (chi-square, df = its
  number of parameters, p < ``alpha``) and BIC improves (Lambda > df ln n);
- on the held-out runs, the gain is real: with d the whitened change of prediction (fixed by
  the fitting runs), under "no effect" the held-out residual projected on d is pure noise,
  ``z = w0 . d / (s |d|)`` is standard normal; the one-sided p, Bonferroni-corrected for the
  number of candidates compared in the round, must be below ``alpha``;
- the gain is positive.

Selection stops at the first round whose best candidate fails. If what is selected then
leaves structure in the held-out residuals (see Verdict), each selected effect is tried swapped
for each other effect, keeping a swap when it improves the held-out fit significantly (greedy
forward steps can start wrong: a strong turn scale first looks like a turn shift), then
each effect is dropped whose removal the held-out runs do not significantly reject (or whose
held-out gain is below ln n, a BIC-like price of one parameter). The
runner-up of an accepted round is called alike when the held-out data cannot reject it
against the winner (the same z-test between the two, or a held-out -2 log-likelihood
difference under 3.84), and the finding is then worded "consistent with A or B".

Verdict. After selection the held-out residuals are tested for structure that a flexible
model would still explain: a free offset per gait cycle id and component, an offset on the first
cycle after a gait change, a drift proportional to time since power-on, and a constant
world-frame drift (an F-test in whitened units, p < ``STRUCTURE_ALPHA``), and their variance is
compared with the noise floor (ratio above ``RATIO_MAX``). Either says the gap is
``partly_unexplained``; otherwise the verdict is ``explained`` when effects were selected and
``no_significant_gap`` when none were.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from pac_host.diagnose import stats
from pac_host.diagnose.fit import CHI2_1_95, FitResult, Problem, fit_effects, n_params
from pac_host.diagnose.residuals import end_errors, step_residuals
from pac_host.model.effects import EFFECT_SPECS, Effect
from pac_host.model.kinematics import to_body_frame
from pac_host.model.table import COMPONENTS

ALPHA = 0.01
STRUCTURE_ALPHA = 0.001
RATIO_MAX = 1.5
MAX_EFFECTS = 3
MIN_STEPS_PER_ID = 3


@dataclass
class Candidate:
    """One effect set fitted on the fitting runs and scored on the held-out runs."""

    name: str
    fit: FitResult
    lr: float
    p_lr: float
    delta_bic: float
    gain: float  # held-out whitened SSR before - after
    z: float
    p_holdout: float
    signal_holdout: float  # |d|^2: how strongly the held-out runs can show the fitted change
    w_after: np.ndarray = field(repr=False)

    @property
    def effect(self) -> Effect:
        return next(e for e in self.fit.effects if e.name == self.name)


@dataclass
class Selection:
    candidates: list[Candidate]  # first round: each effect alone, best held-out gain first
    selected: list[Effect]
    steps: list[dict]
    alike: dict[str, list[str]]
    structure: dict
    verdict: str
    final_fit: FitResult | None = None  # the joint fit of the selected effects
    last_round: list[Candidate] = field(default_factory=list)  # the round that stopped it

    def intervals(self, name: str) -> dict:
        """95% intervals of a selected effect's parameters from the joint fit."""
        return self.final_fit.intervals.get(name, {}) if self.final_fit else {}


def library_names(library: Sequence[str] | None, base: Sequence[Effect]) -> list[str]:
    """The effects to try: the whole library (or a restriction), minus the model's own."""
    names = list(EFFECT_SPECS) if library is None else list(library)
    have = {e.name for e in base}
    return [n for n in EFFECT_SPECS if n in names and n not in have]


def _round(fit_prob: Problem, hold_prob: Problem, names: list[str], current: dict,
           ssr_cur: float, w0: np.ndarray, n_fit: int, n_hold: int) -> list[Candidate]:
    out = []
    for n in names:
        fr = fit_effects(fit_prob, list(current) + [n], start=current)
        df = n_params(n)
        lr = max(ssr_cur - fr.ssr, 0.0) / fr.sigma2
        w1 = hold_prob.whitened(fr.effects)
        gain = float(w0 @ w0 - w1 @ w1)
        s2 = max(float(w1 @ w1) / max(n_hold, 1), 1e-12)
        z, p = stats.projection_p(w0, w1, s2)
        d = w0 - w1
        out.append(Candidate(n, fr, lr, float(chi2.sf(lr, df)), -lr + df * math.log(n_fit),
                             gain, z, p, float(d @ d), w1))
    out.sort(key=lambda c: -c.gain)
    return out


def forward_select(fit_prob: Problem, hold_prob: Problem, library: Sequence[str] | None = None,
                   alpha: float = ALPHA, max_effects: int = MAX_EFFECTS) -> Selection:
    """Forward selection of effects; ``library`` restricts the effects tried (by name)."""
    names = library_names(library, fit_prob.base_effects)
    n_fit, n_hold = fit_prob.n_obs, hold_prob.n_obs
    current: dict[str, Effect] = {}
    ssr_cur = float(fit_prob.ssr_per_run([]).sum())
    w0 = hold_prob.whitened([])
    first: list[Candidate] | None = None
    final: FitResult | None = None
    steps, alike = [], {}
    stopped: list[Candidate] = []
    while len(current) < max_effects:
        remaining = [n for n in names if n not in current]
        if not remaining:
            break
        cands = _round(fit_prob, hold_prob, remaining, current, ssr_cur, w0, n_fit, n_hold)
        if first is None:
            first = cands
        best = cands[0]
        p_adj = min(1.0, best.p_holdout * len(cands))
        ok = best.gain > 0 and p_adj < alpha and best.p_lr < alpha and best.delta_bic < 0
        steps.append({"effect": best.name, "accepted": bool(ok), "p_holdout_adj": p_adj,
                      "p_lr": best.p_lr, "delta_bic": best.delta_bic, "gain": best.gain})
        if not ok:
            stopped = cands
            break
        s2 = max(float(best.w_after @ best.w_after) / max(n_hold, 1), 1e-12)
        alike[best.name] = [
            c.name for c in cands[1:]
            if c.gain > 0 and (best.gain - c.gain < CHI2_1_95
                               or stats.projection_p(c.w_after, best.w_after, s2)[1] > alpha)
        ]
        current = {e.name: e for e in best.fit.effects}
        ssr_cur, w0, final = best.fit.ssr, best.w_after, best.fit
    structure = structure_test(hold_prob, list(current.values()))
    if current and _unexplained(structure):
        # greedy selection can take a wrong first step (a strong turn scale looks like a turn
        # shift); try swapping each selected effect for each other one
        current, final, w0, swaps = _swap(fit_prob, hold_prob, names, current, final, w0, alpha)
        if swaps:
            steps += swaps
            structure = structure_test(hold_prob, list(current.values()))
            alike = {k: v for k, v in alike.items() if k in current}
    selected = list(current.values())
    unexplained = _unexplained(structure)
    if unexplained:
        verdict = "partly_unexplained"
    else:
        verdict = "explained" if selected else "no_significant_gap"
    return Selection(first or [], selected, steps, alike, structure, verdict, final, stopped)


def _unexplained(structure: dict) -> bool:
    return structure["p_value"] < STRUCTURE_ALPHA or structure["variance_ratio"] > RATIO_MAX


def _swap(fit_prob, hold_prob, names, current, final, w0, alpha, max_passes: int = 3):
    """Swap a selected effect for an unselected one while that improves the held-out fit
    significantly (the held-out projection test of :func:`forward_select`)."""
    swaps = []
    n_hold = hold_prob.n_obs
    for _ in range(max_passes):
        best = None
        for out in current:
            keep = {k: v for k, v in current.items() if k != out}
            for new in names:
                if new in current:
                    continue
                fr = fit_effects(fit_prob, list(keep) + [new], start=keep)
                w1 = hold_prob.whitened(fr.effects)
                gain = float(w0 @ w0 - w1 @ w1)
                if best is None or gain > best[0]:
                    best = (gain, out, new, fr, w1)
        if best is None or best[0] <= 0:
            break
        gain, out, new, fr, w1 = best
        s2 = max(float(w1 @ w1) / max(n_hold, 1), 1e-12)
        _, p = stats.projection_p(w0, w1, s2)
        if p >= alpha or gain < math.log(n_hold):
            break
        swaps.append({"effect": new, "replaces": out, "accepted": True, "p_holdout": p,
                      "gain": gain})
        current = {e.name: e for e in fr.effects}
        final, w0 = fr, w1
    # then drop what the held-out runs no longer need (e.g. an effect left at neutral)
    for out in list(current):
        if not swaps or len(current) == 1:
            break
        keep = {k: v for k, v in current.items() if k != out}
        fr = fit_effects(fit_prob, list(keep), start=keep)
        w_less = hold_prob.whitened(fr.effects)
        s2 = max(float(w0 @ w0) / max(n_hold, 1), 1e-12)
        _, p = stats.projection_p(w_less, w0, s2)
        needed = float(w_less @ w_less - w0 @ w0)
        if p >= alpha or needed < math.log(n_hold):  # BIC-like: worth a parameter?
            swaps.append({"effect": out, "dropped": True, "p_holdout": p,
                          "gain_if_kept": needed})
            current, final, w0 = {e.name: e for e in fr.effects}, fr, w_less
    return current, final, w0, swaps


def structure_test(prob: Problem, effects: Sequence[Effect]) -> dict:
    """F-test (whitened) of flexible terms on the residuals left by the model plus ``effects``.

    Terms: an offset per gait cycle id and component (ids with at least
    :data:`MIN_STEPS_PER_ID` steps), an offset per component on the first cycle after a gait
    change, a drift per component proportional to cycles since power-on times the predicted
    move, and a constant world-frame drift.
    """
    b = prob.batch
    eff = tuple(prob.base_effects) + tuple(effects)
    res = step_residuals(prob.rows, b, eff)
    pred = b.observed - res
    m = b.mask[..., None]
    cols = []
    for g in range(32):
        sel = (b.ids == g) & b.mask
        if sel.sum() >= MIN_STEPS_PER_ID:
            for j in range(3):
                x = np.zeros(res.shape)
                x[..., j] = sel
                cols.append(x)
    change = np.zeros(b.mask.shape)
    change[:, 1:] = b.ids[:, 1:] != b.ids[:, :-1]
    t = (b.n0[:, None] + np.arange(b.ids.shape[1])[None]) * b.mask
    t = t / max(float(t.max()), 1.0)
    for j in range(3):
        x = np.zeros(res.shape)
        x[..., j] = change
        cols.append(x * m)
        x = np.zeros(res.shape)
        x[..., j] = t * pred[..., j]
        cols.append(x * m)
    h = b.poses[:, :-1, 2]
    for dx, dy in ((1.0, 0.0), (0.0, 1.0)):
        f, tt = to_body_frame(np.full(h.shape, dx), np.full(h.shape, dy), h)
        cols.append(np.stack([f, tt, np.zeros_like(f)], axis=-1) * m)
    w = prob.whitener.whiten(res).ravel()
    xw = prob.whitener.whiten(np.stack(cols)).reshape(len(cols), -1).T
    coef, _, rank, _ = np.linalg.lstsq(xw, w, rcond=None)
    ssr = float(w @ w)
    resid = w - xw @ coef
    ssr_res = float(resid @ resid)
    n = prob.n_obs
    s2 = ssr_res / max(n - rank, 1)
    stat = (ssr - ssr_res) / s2 if s2 > 0 else 0.0
    return {"terms": int(rank), "statistic": round(stat, 3),
            "p_value": float(chi2.sf(stat, max(rank, 1))),
            "variance_ratio": round(ssr / max(n, 1), 4),
            "components_rms": {c: round(float(np.sqrt((res[..., j][b.mask] ** 2).mean())), 4)
                               for j, c in enumerate(COMPONENTS)}}


def holdout_figures(prob: Problem, effects: Sequence[Effect]) -> tuple[dict, np.ndarray]:
    """Raw held-out step rms per component and per-run rollout end errors for a model."""
    eff = tuple(prob.base_effects) + tuple(effects)
    res = step_residuals(prob.rows, prob.batch, eff)[prob.batch.mask]
    rms = {c: float(np.sqrt((res[:, j] ** 2).mean())) for j, c in enumerate(COMPONENTS)}
    return rms, end_errors(prob.rows, prob.batch, eff)
