"""Propose what the library lacks: candidate terms, chosen sparsely, validated on held-out runs.

When the residual left by the library's effects has structure (:mod:`.shape`), this module
searches a library of candidate terms for it, SINDy-style: each family of terms (below) is a
set of columns in the space of one-step residuals (F, T, dH per step); within a family,
forward stepwise least squares on the whitened fitting residuals adds the column that lowers
the sum of squares most while BIC improves (at most :data:`MAX_TERMS`), with a family's own
hyper-parameter (a period, a change point) chosen by BIC too. Every family's fit is then judged
on the held-out runs like every effect is: the held-out log-likelihood gain, its one-sided
projection p (Bonferroni over the families), and the held-out rollout end-error shrink of the
model with the term added (pose-dependent terms iterated to a fixed point along the replay).

Families (the kind each names):

- ``periodic``: sine and cosine of the cycle index at the periodogram's peak period, counted
  from the run's start and from power-on;
- ``heading``: sine and cosine of the heading and of twice it;
- ``position``: the model's move scaled in bands of x (30 cm) and of y (sextiles), and a
  linear gradient in x and y;
- ``time_since_power_on``: the move scaled by powers of the time since power-on and by
  exp(-t / tau) for a few tau (a warm-up);
- ``sudden_change``: the move scaled from one point of the recorded order of the runs on;
- ``previous_gait_cycle``: the previous gait cycle's move, into each component;
- ``intermittent`` (not a regression): a two-component mixture of the per-step scale of the
  model's move (EM), against one Gaussian, on the held-out runs' likelihood.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats as sps

from pac_host.diagnose import stats
from pac_host.diagnose.fit import Problem
from pac_host.diagnose.noise import NoiseFloor
from pac_host.diagnose.residuals import Batch, predicted_moves, step_residuals
from pac_host.diagnose.shape import innovations, periodogram_test
from pac_host.model.effects import Effect, step_moves
from pac_host.model.kinematics import integrate
from pac_host.model.table import COMPONENTS

MAX_TERMS = 6
ALPHA = 0.01
TAUS = (15.0, 40.0, 100.0, 250.0)
MIN_MOVE_CM = 3.0
POSITION_BINS = 12  # steps whose model move is shorter do not tell a scale
ROLLOUT_PASSES = 4


@dataclass(frozen=True)
class Context:
    """What candidate terms are built from, for one batch of runs."""

    batch: Batch
    pred: np.ndarray  # (R, N, 3) the moves predicted by the model and the selected effects
    poses: np.ndarray  # (R, N, 3) the pose before each step (observed, or replayed)
    chron: np.ndarray  # (R,) each run's place in the recorded order, 0 .. 1


def _per_component(x: np.ndarray) -> list[np.ndarray]:
    """A feature (R, N) as three columns (R, N, 3), one per component."""
    out = []
    for j in range(3):
        c = np.zeros(x.shape + (3,))
        c[..., j] = x
        out.append(c)
    return out


def _scaled(pred: np.ndarray, x: np.ndarray) -> list[np.ndarray]:
    """The model's move times a feature (R, N), one column per component."""
    out = []
    for j in range(3):
        c = np.zeros(pred.shape)
        c[..., j] = pred[..., j] * x
        out.append(c)
    return out


def _time(ctx: Context) -> np.ndarray:
    b = ctx.batch
    return (b.n0[:, None] + np.arange(b.ids.shape[1])[None]).astype(float)


@dataclass(frozen=True)
class Family:
    name: str  # also the kind it names
    columns: Callable[[Context, object], tuple[list[np.ndarray], list[str]]]
    hypers: Callable[[Context, Problem], list] = lambda ctx, prob: [None]
    pose_dependent: bool = False
    n_hyper: int = 0
    # a faster search of the hyper-parameter than one stepwise fit per value: (ctx, prob, w)
    # -> the values worth a stepwise fit
    search: Callable | None = None
    # the columns of the family's F-test, for each of its hypers (default: columns, hypers)
    test_columns: Callable | None = None
    test_hypers: Callable[[Context, Problem], list] | None = None


def _periodic_cols(ctx, period):
    t_run = np.broadcast_to(np.arange(ctx.batch.ids.shape[1], dtype=float)[None],
                            ctx.batch.ids.shape)
    cols, names = [], []
    for label, t in (("cycle", t_run), ("cycles since power-on", _time(ctx))):
        for fn, f in (("sin", np.sin), ("cos", np.cos)):
            x = f(2 * np.pi * t / period)
            cols += _per_component(x)
            names += [f"{fn}(2 pi {label} / {period:.2f}) on {c}" for c in COMPONENTS]
    return cols, names


def _periodic_hypers(ctx, prob):
    e, mask = innovations(prob, ())
    _, _, period, _ = periodogram_test(e, mask)
    if not math.isfinite(period):
        return []
    return list(period * np.linspace(0.9, 1.1, 41))


def _periodic_search(ctx, prob, w):
    """The period by full least squares on a grid around the periodogram's peak, then on a
    finer grid around the best (a phase locked to power-on needs the period to 0.1%). The
    search weighs the raw residuals per component (no whitening: only the period is chosen
    here)."""
    grid = _periodic_hypers(ctx, prob)
    if not grid:
        return []
    b = prob.batch
    res = step_residuals(prob.rows, b, prob.base_effects)[b.mask]
    scale = np.maximum(res.std(axis=0), 1e-9)
    y = (res / scale).ravel()

    def ssr_at(period: float) -> float:
        cols = _periodic_cols(ctx, period)[0]
        x = np.stack([c[b.mask] / scale for c in cols], axis=-1).reshape(len(y), -1)
        return _least_squares(x, y)[1]

    for _ in range(2):
        ssr = [ssr_at(p) for p in grid]
        k = int(np.argmin(ssr))
        step = (grid[1] - grid[0]) if len(grid) > 1 else 0.0
        best = grid[k]
        grid = list(best + np.linspace(-step, step, 21))
    return [best]


def _heading_cols(ctx, _):
    h = np.radians(ctx.poses[..., 2])
    cols, names = [], []
    for fn, x in (("sin h", np.sin(h)), ("cos h", np.cos(h)), ("sin 2h", np.sin(2 * h)),
                  ("cos 2h", np.cos(2 * h))):
        cols += _per_component(x)
        names += [f"{fn} on {c}" for c in COMPONENTS]
    return cols, names


def _edges(ctx: Context) -> list[np.ndarray]:
    """Bin edges of x and y: quantiles of the positions visited (the outer ones open)."""
    out = []
    for a in range(2):
        v = ctx.poses[..., a][ctx.batch.mask]
        e = np.unique(np.quantile(v, np.linspace(0, 1, POSITION_BINS + 1)).round(1))
        e[0], e[-1] = -np.inf, np.inf
        out.append(e)
    return out


def _band(ctx: Context, axis: int, lo: float, hi: float) -> np.ndarray:
    v = ctx.poses[..., axis]
    return ((v >= lo) & (v < hi)).astype(float)


def _position_cols(ctx, band):
    """The move scaled inside a band of x or y: (axis, lo, hi)."""
    axis, lo, hi = band
    where = f"{lo:.0f} <= {'xy'[axis]} < {hi:.0f} cm".replace("-inf <= ", "").replace(
        " < inf cm", " (and beyond)")
    return _scaled(ctx.pred, _band(ctx, axis, lo, hi)), [f"{c} scaled where {where}"
                                                          for c in COMPONENTS]


def _position_bins(ctx, _):
    cols, names = [], []
    for axis, e in enumerate(_edges(ctx)):
        for lo, hi in zip(e[:-1], e[1:], strict=True):
            c, n = _position_cols(ctx, (axis, lo, hi))
            cols += c
            names += n
    return cols, names


def _position_search(ctx, prob, w):
    """Every band of consecutive bins on each axis, from sums of the whitened bin columns
    (whitening is linear); the best few go on to the stepwise fit."""
    scored = []
    for axis, e in enumerate(_edges(ctx)):
        nb = len(e) - 1
        xw = _whiten_cols(prob, [c for lo, hi in zip(e[:-1], e[1:], strict=True)
                                 for c in _position_cols(ctx, (axis, lo, hi))[0]])
        cum = np.concatenate([np.zeros((len(w), 1, 3)),
                              np.cumsum(xw.reshape(len(w), nb, 3), axis=1)], axis=1)
        for a in range(nb):
            for b in range(a + 1, nb + 1):
                if a == 0 and b == nb:
                    continue  # the whole floor: a scale the library has
                scored.append((_least_squares(cum[:, b] - cum[:, a], w)[1], (axis, e[a], e[b])))
    scored.sort(key=lambda t: t[0])
    return [h for _, h in scored[:3]]


def _time_hypers(ctx, prob):
    return [max(float(_time(ctx)[ctx.batch.mask].max()), 1.0)]


def _time_cols(ctx, t_max):
    t = _time(ctx)
    cols, names = [], []
    for label, x in ([("t/T", t / t_max), ("(t/T)^2", (t / t_max) ** 2)]
                     + [(f"exp(-t/{tau:.0f})", np.exp(-t / tau)) for tau in TAUS]):
        cols += _scaled(ctx.pred, x)
        names += [f"{c} scaled by {label} (t: cycles since power-on, T = {t_max:.0f})"
                  for c in COMPONENTS]
    return cols, names


def _change_hypers(ctx, prob):
    c = np.sort(ctx.chron)
    mids = (c[1:] + c[:-1]) / 2.0
    return [float(m) for m in mids[1:-1]] if len(mids) > 2 else []


def _change_search(ctx, prob, w):
    """Every change point, from the whitened model moves masked run by run (the whitening
    acts within a run); the best few go on to the stepwise fit."""
    runs = _whiten_cols(prob, _scaled(ctx.pred, np.ones(ctx.batch.ids.shape)))
    runs = runs.reshape(len(ctx.chron), -1, 3)
    wr = w.reshape(len(ctx.chron), -1)
    scored = []
    for at in _change_hypers(ctx, prob):
        after = ctx.chron >= at
        scored.append((_least_squares(runs[after].reshape(-1, 3), wr[after].ravel())[1]
                       + float((wr[~after] ** 2).sum()) - float((w @ w)), at))
    scored.sort(key=lambda t: t[0])
    return [h for _, h in scored[:3]]


def _change_cols(ctx, at):
    after = np.broadcast_to((ctx.chron >= at)[:, None], ctx.batch.ids.shape).astype(float)
    return _scaled(ctx.pred, after), [f"{c} scaled from {at:.0%} of the recorded runs on"
                                      for c in COMPONENTS]


def _previous_cols(ctx, _):
    prev = np.zeros(ctx.pred.shape)
    prev[:, 1:] = ctx.pred[:, :-1]
    cols, names = [], []
    for k, ck in enumerate(COMPONENTS):
        cols += _per_component(prev[..., k])
        names += [f"previous cycle's {ck} on {c}" for c in COMPONENTS]
    return cols, names


FAMILIES = (
    Family("periodic", _periodic_cols, _periodic_hypers, n_hyper=1, search=_periodic_search),
    Family("heading", _heading_cols, pose_dependent=True),
    Family("position", _position_cols, pose_dependent=True, n_hyper=2,
           search=_position_search, test_columns=_position_bins,
           test_hypers=lambda ctx, prob: [None]),
    Family("time_since_power_on", _time_cols, _time_hypers),
    Family("sudden_change", _change_cols, _change_hypers, n_hyper=1, search=_change_search),
    Family("previous_gait_cycle", _previous_cols),
)
KIND_WORDS = {
    "periodic": "periodic in the cycle index", "heading": "dependent on heading",
    "position": "dependent on position", "time_since_power_on": "dependent on time since "
    "power-on", "sudden_change": "a sudden change in the recorded order of the runs",
    "previous_gait_cycle": "dependent on the previous gait cycle",
    "intermittent": "intermittent",
}


def context(prob: Problem, effects: Sequence[Effect], chron: np.ndarray,
            poses: np.ndarray | None = None) -> Context:
    b = prob.batch
    eff = tuple(prob.base_effects) + tuple(effects)
    return Context(b, predicted_moves(prob.rows, b, eff),
                   b.poses[:, :-1] if poses is None else poses, chron)


def _whiten_cols(prob: Problem, cols: list[np.ndarray]) -> np.ndarray:
    x = np.stack(cols) * prob.batch.mask[None, ..., None]
    return prob.whitener.whiten(x).reshape(len(cols), -1).T


def _least_squares(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """Coefficients and residual sum of squares of y on the columns of x (normal equations,
    with a tiny ridge so that empty or repeated columns do not break it)."""
    a = x.T @ x
    coef = np.linalg.solve(a + 1e-10 * (np.trace(a) / max(len(a), 1) + 1e-12) * np.eye(len(a)),
                           x.T @ y)
    r = y - x @ coef
    return coef, float(r @ r)


def _stepwise(xw: np.ndarray, w: np.ndarray, n_hyper: int) -> tuple[list[int], np.ndarray, float]:
    """Forward selection of columns by BIC; returns (chosen, coefficients, bic)."""
    n = len(w)
    chosen: list[int] = []
    coef = np.zeros(0)
    ssr = float(w @ w)
    bic = n * math.log(max(ssr, 1e-300) / n)
    norms = (xw**2).sum(axis=0)
    while len(chosen) < MAX_TERMS:
        r = w - (xw[:, chosen] @ coef if chosen else 0.0)
        score = (xw.T @ r) ** 2 / np.where(norms > 1e-12, norms, np.inf)
        score[chosen] = -1.0
        k = int(np.argmax(score))
        if score[k] <= 0:
            break
        trial = chosen + [k]
        c, s = _least_squares(xw[:, trial], w)
        b = n * math.log(max(s, 1e-300) / n) + (len(trial) + n_hyper) * math.log(n)
        if b >= bic:
            break
        chosen, coef, ssr, bic = trial, c, s, b
    return chosen, coef, bic


@dataclass
class Proposal:
    family: str
    kind: str
    terms: list[dict]  # [{term, coefficient}]
    hyper: object
    fit_gain: float  # fitting runs: whitened SSR before - after
    holdout_gain: float  # held-out runs: whitened SSR before - after (2 x log-likelihood gain)
    z: float
    p_value: float  # Bonferroni over the families
    shrink: float  # held-out rollout end error, 1 - after / the model's own
    rollout_cm: tuple[float, float, float]  # model alone, model + library effects, proposal

    description: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def shrink_over_library(self) -> float:
        """What the proposal adds to the library's effects (1 - after / library's)."""
        return 1.0 - self.rollout_cm[2] / self.rollout_cm[1] if self.rollout_cm[1] else 0.0

    def to_json(self) -> dict:
        return {"family": self.family, "kind": self.kind, "terms": self.terms,
                "description": self.description,
                "fit": {"whitened_ssr_gain": round(self.fit_gain, 3)},
                "holdout": {"loglik_gain": round(self.holdout_gain / 2.0, 3),
                            "z": round(self.z, 3), "p_value": self.p_value,
                            "rollout_cm_model": round(self.rollout_cm[0], 3),
                            "rollout_cm_library": round(self.rollout_cm[1], 3),
                            "rollout_cm_after": round(self.rollout_cm[2], 3),
                            "shrink": round(self.shrink, 4),
                            "shrink_over_library": round(self.shrink_over_library, 4)},
                **self.extra}


def _delta(fam: Family, ctx: Context, hyper, chosen: list[int], coef: np.ndarray
           ) -> np.ndarray:
    cols, _ = fam.columns(ctx, hyper)
    out = np.zeros(ctx.pred.shape)
    for k, c in zip(chosen, coef, strict=True):
        out += c * cols[k]
    return out * ctx.batch.mask[..., None]


def _replay(prob: Problem, effects: Sequence[Effect], fam: Family | None = None, hyper=None,
            chosen: Sequence[int] = (), coef: np.ndarray | None = None,
            chron: np.ndarray | None = None) -> np.ndarray:
    """Poses (R, N + 1, 3) of the model plus ``effects`` plus a family's term, replayed from
    each run's start; a pose-dependent term is evaluated at the replayed pose, step by step."""
    b = prob.batch
    body, world = step_moves(prob.rows, b.ids, tuple(prob.base_effects) + tuple(effects), b.n0)
    body = body * b.mask[..., None]
    if world is not None:
        world = world * b.mask[..., None]
    if fam is None or not len(chosen):
        return integrate(b.poses[:, 0], body, world)
    ctx = context(prob, effects, chron)
    if not fam.pose_dependent:
        return integrate(b.poses[:, 0], body + _delta(fam, ctx, hyper, chosen, coef), world)
    poses = np.empty(b.poses.shape)
    poses[:, 0] = b.poses[:, 0]
    before = ctx.poses.copy()
    for i in range(b.ids.shape[1]):
        before[:, i] = poses[:, i]
        step = Context(ctx.batch, ctx.pred, before, chron)
        d = _delta(fam, step, hyper, chosen, coef)[:, i]
        w = None if world is None else world[:, i : i + 1]
        poses[:, i + 1] = integrate(poses[:, i], (body[:, i] + d)[:, None], w)[:, -1]
    return poses


def _end_error(prob: Problem, poses: np.ndarray) -> np.ndarray:
    b = prob.batch
    k = np.arange(len(b.lengths))
    d = poses[k, b.lengths, :2] - b.poses[k, b.lengths, :2]
    return np.hypot(d[:, 0], d[:, 1])


def fit_family(fam: Family, fit_p: Problem, effects: Sequence[Effect], chron_fit: np.ndarray):
    """Best (hyper, chosen columns, coefficients, bic, fit gain, standard errors) of a family
    on the fitting runs, on top of the model plus ``effects``."""
    ctx = context(fit_p, effects, chron_fit)
    w = fit_p.whitened(effects)
    through = _through(fit_p, effects)
    hypers = fam.search(ctx, through, w) if fam.search else fam.hypers(ctx, through)
    best = None
    for hyper in hypers:
        cols, _ = fam.columns(ctx, hyper)
        xw = _whiten_cols(fit_p, cols)
        chosen, coef, bic = _stepwise(xw, w, fam.n_hyper)
        if chosen and (best is None or bic < best[3]):
            x = xw[:, chosen]
            r = w - x @ coef
            gain = float(w @ w - r @ r)
            # standard errors from the curvature, scaled by the residual variance
            s2 = float(r @ r) / max(len(w) - len(chosen), 1)
            try:
                se = np.sqrt(np.maximum(np.diag(np.linalg.inv(x.T @ x)) * s2, 0.0))
            except np.linalg.LinAlgError:
                se = np.full(len(chosen), np.nan)
            best = (hyper, chosen, coef, bic, gain, se)
    return best


def _through(prob: Problem, effects: Sequence[Effect]) -> Problem:
    """The problem with ``effects`` made part of the model (for a family's hyper search)."""
    return Problem(prob.rows, tuple(prob.base_effects) + tuple(effects), prob.batch,
                   prob.whitener)


def propose(fit_p: Problem, hold_p: Problem, effects: Sequence[Effect], chron_fit: np.ndarray,
            chron_hold: np.ndarray, noise: NoiseFloor) -> tuple[list[Proposal], dict | None]:
    """Every family fitted and judged on the held-out runs (best held-out gain first), and the
    intermittent mixture's figures (or None).

    A family's term is fitted on top of the selected ``effects`` and on the model alone; the
    fitting runs' BIC (the effects' parameters counted) chooses, since an effect chosen from
    the library may only have stood in for the missing term (a stride scale for a payload
    change). Its held-out figures compare with the model plus ``effects`` either way."""
    w0 = hold_p.whitened(effects)
    end_model = _end_error(hold_p, _replay(hold_p, ()))
    end0 = _end_error(hold_p, _replay(hold_p, effects))
    n_fit = fit_p.n_obs
    k_eff = sum(len(e.params) for e in effects)
    ssr_eff = float(fit_p.whitened(effects) @ fit_p.whitened(effects))
    ssr_none = float(fit_p.whitened([]) @ fit_p.whitened([]))
    out = []
    for fam in FAMILIES:
        options = []
        for base in ((tuple(effects), ()) if effects else ((),)):
            best = fit_family(fam, fit_p, base, chron_fit)
            if best is None:
                continue
            ssr = (ssr_eff if base else ssr_none) - best[4]
            # BIC of the whole model on the fitting runs, the scale of the whitened sum free
            bic = n_fit * math.log(max(ssr, 1e-300) / n_fit) + (
                len(best[1]) + fam.n_hyper + (k_eff if base else 0)) * math.log(n_fit)
            options.append((bic, base, best))
        if not options:
            continue
        _, base, (hyper, chosen, coef, _, gain, se) = min(options, key=lambda t: t[0])
        hctx = context(hold_p, base, chron_hold)
        delta = _delta(fam, hctx, hyper, chosen, coef)
        res = step_residuals(hold_p.rows, hold_p.batch,
                             tuple(hold_p.base_effects) + tuple(base)) - delta
        w1 = hold_p.whitener.whiten(res).ravel()
        s2 = max(float(w1 @ w1) / max(hold_p.n_obs, 1), 1e-12)
        z, p = stats.projection_p(w0, w1, s2)
        end1 = _end_error(hold_p, _replay(hold_p, base, fam, hyper, chosen, coef, chron_hold))
        shrink = 1.0 - end1.sum() / end_model.sum() if end_model.sum() > 0 else 0.0
        _, names = fam.columns(context(fit_p, base, chron_fit), hyper)
        terms = [{"term": names[k], "coefficient": round(float(c), 5),
                  "interval_95": [round(float(c - 1.96 * e), 5), round(float(c + 1.96 * e), 5)]}
                 for k, c, e in zip(chosen, coef, se, strict=True)]
        prop = Proposal(fam.name, fam.name, terms, hyper, gain, float(w0 @ w0 - w1 @ w1), z,
                        min(1.0, p * len(FAMILIES)), float(shrink),
                        (float(end_model.mean()), float(end0.mean()), float(end1.mean())))
        prop.extra = {"with_library_effects": [str(e) for e in base],
                      "replaces": [str(e) for e in effects if e not in base]}
        prop.description = describe(prop, hold_p, hctx, fam, chosen, coef)
        out.append(prop)
    out.sort(key=lambda q: -q.holdout_gain)
    mix = intermittent(fit_p, hold_p, noise)
    if mix is not None:  # the mixture's expected move, replayed on the model alone
        b = hold_p.batch
        body, world = step_moves(hold_p.rows, b.ids, hold_p.base_effects, b.n0)
        body = body * mix["expected_scale"] * b.mask[..., None]
        world = None if world is None else world * b.mask[..., None]
        end1 = _end_error(hold_p, integrate(b.poses[:, 0], body, world))
        mix["holdout"] = {
            "rollout_cm_model": round(float(end_model.mean()), 3),
            "rollout_cm_library": round(float(end0.mean()), 3),
            "rollout_cm_after": round(float(end1.mean()), 3),
            "shrink": round(1.0 - float(end1.sum() / end_model.sum()), 4)
            if end_model.sum() > 0 else 0.0,
            "shrink_over_library": round(1.0 - float(end1.sum() / end0.sum()), 4)
            if end0.sum() > 0 else 0.0}
    return out, mix


def describe(prop: Proposal, prob: Problem, ctx: Context, fam: Family, chosen, coef) -> str:
    """Words and numbers: what the term does, in the units of the moves."""
    delta = _delta(fam, ctx, prop.hyper, chosen, coef)
    flat = delta[prob.batch.mask]
    amp = np.sqrt(2.0) * np.sqrt((flat**2).mean(axis=0))  # a sine's amplitude from its rms
    j = int(np.argmax(amp))
    unit = "deg" if j == 2 else "cm"
    what = KIND_WORDS[fam.name]
    if fam.name == "periodic":
        return (f"{what}, period about {prop.hyper:.1f} gait cycles, amplitude about "
                f"{amp[j]:.1f} {unit} on {COMPONENTS[j]}")
    if fam.name == "sudden_change":
        after = prob.batch.mask & (ctx.chron >= prop.hyper)[:, None]
        rel = _relative_change(ctx, delta, after)
        return f"{what}: from {prop.hyper:.0%} of the runs on, the move is {rel}"
    if fam.name == "position":
        axis, lo, hi = prop.hyper
        where = f"{lo:.0f} <= {'xy'[axis]} < {hi:.0f} cm".replace("-inf <= ", "").replace(
            " < inf cm", " cm and beyond")
        inside = (_band(ctx, axis, lo, hi) > 0) & prob.batch.mask
        return f"{what}: where {where} the move is {_relative_change(ctx, delta, inside)}"
    if fam.name == "time_since_power_on":  # the term on a time line, as a share of the move
        n = 301
        line = Batch(("t",), np.zeros((1, n), dtype=np.int64), np.ones((1, n), dtype=bool),
                     np.zeros((1, n + 1, 3)), np.zeros(1, dtype=np.int64), np.array([n]))
        g = Context(line, np.ones((1, n, 3)), np.zeros((1, n, 3)), ctx.chron)
        cols, _ = fam.columns(g, prop.hyper)
        rel = sum(c * cols[k][0] for k, c in zip(chosen, coef, strict=True))
        jj = int(np.argmax(np.abs(rel).max(axis=0)))
        return (f"{what}: {COMPONENTS[jj]} "
                + ", ".join(f"{rel[t, jj]:+.0%} at {t} cycles" for t in (0, 50, 150, 300)))
    if fam.name == "heading":
        grid = np.arange(0.0, 360.0, 5.0)
        g = Context(ctx.batch, np.zeros((1, len(grid), 3)),
                    np.stack([np.zeros_like(grid), np.zeros_like(grid), grid], -1)[None], ctx.chron)
        cols, _ = fam.columns(g, prop.hyper)
        curve = sum(c * cols[k][0] for k, c in zip(chosen, coef, strict=True))
        k = int(np.argmax(np.abs(curve[:, j])))
        return (f"{what}: {COMPONENTS[j]} changes by up to {curve[k, j]:+.1f} {unit} per gait "
                f"cycle, most at heading {grid[k]:.0f} deg "
                f"(and {curve[(k + 36) % 72, j]:+.1f} at {grid[(k + 36) % 72]:.0f})")
    size = float(np.abs(flat[:, j]).max())
    return f"{what}: up to {size:.1f} {unit} on {COMPONENTS[j]} ({prop.terms[0]['term']}, ...)"


def _relative_change(ctx: Context, delta: np.ndarray, where: np.ndarray) -> str:
    """The correction on the steps ``where`` as a share of the model's move, per component."""
    pred, d = ctx.pred[where], delta[where]
    parts = []
    for j, c in enumerate(COMPONENTS):
        scale = np.abs(pred[:, j]).sum()
        if scale > 0:
            r = float((d[:, j] * np.sign(pred[:, j])).sum() / scale)
            if abs(r) >= 0.01:
                parts.append(f"{c} {r:+.0%}")
    return ", ".join(parts) or "unchanged"


# --- intermittent: a mixture of per-step scales --------------------------------------------

def _scales(prob: Problem, noise: NoiseFloor) -> tuple[np.ndarray, np.ndarray]:
    """Per step: the observed move's scale against the model's own (F, T) and its variance."""
    b = prob.batch
    base = predicted_moves(prob.rows, b, tuple(prob.base_effects))
    ft = base[..., :2]
    n2 = (ft**2).sum(axis=-1)
    ok = b.mask & (np.sqrt(n2) >= MIN_MOVE_CM)
    rho = (b.observed[..., :2] * ft).sum(axis=-1) / np.where(ok, n2, 1.0)
    var = (2 * noise.pos_cm**2 + noise.step_cm**2
           + (np.radians(noise.heading_deg) ** 2) * n2) / np.where(ok, n2, 1.0)
    return rho[ok], var[ok]


def _loglik(x, v, ps, ms, tau2):
    dens = sum(p * sps.norm.pdf(x, m, np.sqrt(v + tau2)) for p, m in zip(ps, ms, strict=True))
    return np.log(np.maximum(dens, 1e-300))


def _em(x: np.ndarray, v: np.ndarray, iters: int = 200):
    """Two-component mixture of scales: weights, means, shared extra variance."""
    m = np.quantile(x, [0.95, 0.05])
    ps = np.array([0.8, 0.2])
    tau2 = 1e-3
    for _ in range(iters):
        dens = np.stack([p * sps.norm.pdf(x, mu, np.sqrt(v + tau2)) for p, mu in zip(ps, m,
                                                                                   strict=True)])
        g = dens / np.maximum(dens.sum(axis=0), 1e-300)
        ps = np.clip(g.mean(axis=1), 1e-4, 1 - 1e-4)
        wts = g / (v + tau2)
        m = (wts * x).sum(axis=1) / np.maximum(wts.sum(axis=1), 1e-300)
        r2 = (g * (x - m[:, None]) ** 2).sum() / len(x) - float(np.mean(v))
        tau2 = max(r2, 1e-6)
    return ps, m, tau2


def intermittent(fit_p: Problem, hold_p: Problem, noise: NoiseFloor) -> dict | None:
    """The mixture fitted on the fitting runs, judged by the held-out log-likelihood gain over
    one Gaussian; None when too few steps."""
    x, v = _scales(fit_p, noise)
    xh, vh = _scales(hold_p, noise)
    if len(x) < 40 or len(xh) < 10:
        return None
    m0 = float(np.average(x, weights=1 / v))
    tau0 = max(float(np.mean((x - m0) ** 2 - v)), 1e-6)
    ps, ms, tau2 = _em(x, v)
    gain = float((_loglik(xh, vh, ps, ms, tau2) - _loglik(xh, vh, [1.0], [m0], tau0)).sum())
    major = int(np.argmax(ps))
    minor = 1 - major
    return {"share": float(ps[minor]), "scale_minor": float(ms[minor]),
            "scale_major": float(ms[major]), "spread": float(np.sqrt(tau2)),
            "holdout_loglik_gain": gain, "expected_scale": float((ps * ms).sum()),
            "description": (f"intermittent: {ps[minor]:.0%} of gait cycles move "
                            f"{ms[minor]:.0%} of the model's move, the others "
                            f"{ms[major]:.0%}")}


def family_tests(prob: Problem, effects: Sequence[Effect], chron: np.ndarray
                 ) -> dict[str, tuple[str, float, float, str]]:
    """F-tests of each family's full set of columns on ``prob``'s residuals (for the shape
    flag): name -> (kind, p, F, description). A family with a hyper-parameter searched over
    many values (a change point) is Bonferroni-corrected for them."""
    ctx = context(prob, effects, chron)
    w = prob.whitened(effects)
    n = len(w)
    out = {}
    for fam in FAMILIES:
        if fam.name == "periodic":  # the periodogram tests it
            continue
        best = (1.0, 0.0)
        hypers = (fam.test_hypers or fam.hypers)(ctx, _through(prob, effects))
        if fam.name == "sudden_change":  # the F-test at the best few change points
            hypers_tested = _change_search(ctx, _through(prob, effects), w)
        else:
            hypers_tested = hypers
        for hyper in hypers_tested:
            cols, _ = (fam.test_columns or fam.columns)(ctx, hyper)
            xw = _whiten_cols(prob, cols)
            eig = np.linalg.eigvalsh(xw.T @ xw)
            rank = int((eig > 1e-9 * max(float(eig.max()), 1e-300)).sum())
            if rank == 0:
                continue
            ssr1 = _least_squares(xw, w)[1]
            f = ((float(w @ w) - ssr1) / rank) / max(ssr1 / max(n - rank, 1), 1e-300)
            p = float(sps.f.sf(f, rank, max(n - rank, 1)))
            if p < best[0]:
                best = (p, f)
        p = min(1.0, best[0] * max(len(hypers), 1))
        out[fam.name] = (fam.name, p, best[1],
                         f"residuals {KIND_WORDS[fam.name]} (F = {best[1]:.1f})")
    return out
