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

Families (the kind each names). Physics adds as often as it scales, so each covariate enters
in both forms: the model's move *scaled* by it (a share of the move: a weaker stride) and a
term *added* to each component (a fixed length or angle, whatever the move):

- ``periodic``: sine and cosine of the cycle index at the periodogram's peak period, counted
  from the run's start and from power-on, added and scaling the move;
- ``heading``: sine and cosine of the heading and of twice it, added; sine and cosine of the
  heading scaling the move (a carpet's grain);
- ``position``: inside a band of x or of y (bands of quantile bins, searched), the move
  scaled, a term added and a world-frame drift (a ramp); or a gradient over the floor (the
  move scaled by x and y, a drift growing with x and y: a tether);
- ``time_since_power_on``: powers of the time since power-on and exp(-t / tau) for a few tau
  (a warm-up), scaling the move and added (a sag of fixed length);
- ``sudden_change``: from one point of the recorded order of the runs on, the move scaled and
  a term added;
- ``previous_gait_cycle``: the previous gait cycle's move, into each component; the first
  gait cycle after the turn direction reverses (backlash), scaled and added; the previous
  turn's direction, added; exp(-k / tau) of the cycles k since the last gait change (a
  settling), scaled and added;
- ``turn``: confined to one side (right or left turns) or one range of turn strengths (or
  both), the move scaled and a term added (a weak leg; the hardest turns slipping);
- ``time_in_run``: powers of the cycles since the run's start and exp(-i / tau), scaling the
  move and added (a warm-up after every pause between runs);
- ``intermittent`` (not a regression): a two-component mixture of the per-step scale of the
  model's move (EM), against one Gaussian, on the held-out runs' likelihood.

The shape tests (:func:`family_tests`) use each family's first, scaled-only or added-only form
as before (``test_columns``); the forms added since, ``turn`` and ``time_in_run`` only propose.
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
from pac_host.model.kinematics import integrate, to_body_frame
from pac_host.model.table import COMPONENTS, N_IDS, side, strength

MAX_TERMS = 6
ALPHA = 0.01
TAUS = (15.0, 40.0, 100.0, 250.0)
TAUS_RUN = (5.0, 15.0, 40.0)  # time constants of a settling along each run
SETTLE = (1.5, 4.0)  # ... and after each gait change
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


def _world(ctx: Context, x: np.ndarray) -> list[np.ndarray]:
    """A world-frame drift (east, then north) times a feature (R, N), in the body frame of the
    pose before each step: two columns on F and T."""
    out = []
    for dx, dy in ((1.0, 0.0), (0.0, 1.0)):
        f, t = to_body_frame(dx, dy, ctx.poses[..., 2])
        c = np.zeros(ctx.pred.shape)
        c[..., 0], c[..., 1] = f * x, t * x
        out.append(c)
    return out


def _both(ctx: Context, x: np.ndarray, label: str) -> tuple[list[np.ndarray], list[str]]:
    """The move scaled by a feature, and the feature added to each component."""
    return (_scaled(ctx.pred, x) + _per_component(x),
            [f"{c} scaled by {label}" for c in COMPONENTS]
            + [f"{label} added to {c}" for c in COMPONENTS])


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
    shape_test: bool = True  # False: proposes only, no F-test among the shape tests


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


def _periodic_all(ctx, period):
    """The added sines and cosines, and the same scaling the move."""
    cols, names = _periodic_cols(ctx, period)
    for label, t in (("cycle", np.broadcast_to(np.arange(ctx.batch.ids.shape[1], dtype=float)
                                               [None], ctx.batch.ids.shape)),
                     ("cycles since power-on", _time(ctx))):
        for fn, f in (("sin", np.sin), ("cos", np.cos)):
            cols += _scaled(ctx.pred, f(2 * np.pi * t / period))
            names += [f"{c} scaled by {fn}(2 pi {label} / {period:.2f})" for c in COMPONENTS]
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


def _heading_all(ctx, _):
    """The added terms, and the move scaled by the sine and cosine of the heading."""
    cols, names = _heading_cols(ctx, None)
    h = np.radians(ctx.poses[..., 2])
    for fn, x in (("sin h", np.sin(h)), ("cos h", np.cos(h))):
        cols += _scaled(ctx.pred, x)
        names += [f"{c} scaled by {fn}" for c in COMPONENTS]
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


BAND_GRID_CM = 25.0
MAX_SEARCH_BINS = 32


def _search_edges(ctx: Context) -> list[np.ndarray]:
    """Bin edges for the band search: the quantile edges of :func:`_edges` and a grid every
    :data:`BAND_GRID_CM` over the positions visited (sparse tails need it), edges closer than
    a fifth of the grid merged."""
    out = []
    for a, e in enumerate(_edges(ctx)):
        v = ctx.poses[..., a][ctx.batch.mask]
        lo, hi = float(v.min()), float(v.max())
        step = max(BAND_GRID_CM, (hi - lo) / MAX_SEARCH_BINS)
        grid = np.arange(math.floor(lo / step) * step + step, hi, step)
        inner = np.sort(np.concatenate([e[1:-1], grid.round(1)]))
        keep = [x for k, x in enumerate(inner) if k == 0 or x - inner[k - 1] > step / 5]
        out.append(np.array([-np.inf, *keep, np.inf]))
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


def _band_cols(ctx, band) -> tuple[list[np.ndarray], list[str]]:
    """Inside a band of x or y: the move scaled, a term added, a world-frame drift."""
    axis, lo, hi = band
    where = f"{lo:.0f} <= {'xy'[axis]} < {hi:.0f} cm".replace("-inf <= ", "").replace(
        " < inf cm", " (and beyond)")
    x = _band(ctx, axis, lo, hi)
    return (_scaled(ctx.pred, x) + _per_component(x) + _world(ctx, x),
            [f"{c} scaled where {where}" for c in COMPONENTS]
            + [f"added to {c} where {where}" for c in COMPONENTS]
            + [f"world drift {d} where {where}" for d in ("east", "north")])


def _gradient_cols(ctx, hyper) -> tuple[list[np.ndarray], list[str]]:
    """Over the whole floor: the move scaled by x and by y, and a world-frame drift constant
    and growing with x and y (per metre from the centre of the runs)."""
    _, xc, yc = hyper
    dx = (ctx.poses[..., 0] - xc) / 100.0
    dy = (ctx.poses[..., 1] - yc) / 100.0
    one = np.ones(ctx.batch.ids.shape)
    cols = _scaled(ctx.pred, dx) + _scaled(ctx.pred, dy) + _world(ctx, one) + _world(
        ctx, dx) + _world(ctx, dy)
    names = ([f"{c} scaled by (x - {xc:.0f} cm) / m" for c in COMPONENTS]
             + [f"{c} scaled by (y - {yc:.0f} cm) / m" for c in COMPONENTS]
             + [f"world drift {d}" for d in ("east", "north")]
             + [f"world drift {d} x (x - {xc:.0f} cm) / m" for d in ("east", "north")]
             + [f"world drift {d} x (y - {yc:.0f} cm) / m" for d in ("east", "north")])
    return cols, names


def _position_all(ctx, hyper):
    return _gradient_cols(ctx, hyper) if hyper[0] == "gradient" else _band_cols(ctx, hyper)


def _position_search(ctx, prob, w):
    """Every band of consecutive bins on each axis, from sums of the whitened bin columns
    (whitening is linear); the best few go on to the stepwise fit, and the gradient."""
    scored = []
    for axis, e in enumerate(_search_edges(ctx)):
        nb = len(e) - 1
        xw = _whiten_cols(prob, [c for lo, hi in zip(e[:-1], e[1:], strict=True)
                                 for c in _band_cols(ctx, (axis, lo, hi))[0]])
        k = xw.shape[1] // nb
        cum = np.concatenate([np.zeros((1, len(w), k)), np.cumsum(
            np.moveaxis(xw.reshape(len(w), nb, k), 1, 0), axis=0)])
        for a in range(nb):
            ssr = _batched_ssr(cum[a + 1 :] - cum[a], w)
            for b, v in zip(range(a + 1, nb + 1), ssr, strict=True):
                if not (a == 0 and b == nb):  # the whole floor: a scale the library has
                    scored.append((float(v), (axis, e[a], e[b])))
    scored.sort(key=lambda t: t[0])
    m = ctx.batch.mask
    centre = ("gradient", round(float(ctx.poses[..., 0][m].mean())),
              round(float(ctx.poses[..., 1][m].mean())))
    return [h for _, h in scored[:3]] + [centre]


def _time_hypers(ctx, prob):
    return [max(float(_time(ctx)[ctx.batch.mask].max()), 1.0)]


def _decays(x: np.ndarray, span: float, sym: str, big: str, taus) -> list:
    """(label, covariate) pairs of a count ``x``: x/span, its square and exp(-x/tau) for
    each tau, labelled with the count's symbol ``sym`` and the span's ``big``."""
    return ([(f"{sym}/{big}", x / span), (f"({sym}/{big})^2", (x / span) ** 2)]
            + [(f"exp(-{sym}/{tau:.0f})", np.exp(-x / tau)) for tau in taus])


def _both_of(ctx, terms: list, note: str):
    """The move scaled by each covariate of ``terms`` and the same term added
    (:func:`_both`), each name followed by ``note``."""
    cols, names = [], []
    for label, x in terms:
        c, n = _both(ctx, x, label)
        cols += c
        names += [f"{v} ({note})" for v in n]
    return cols, names


def _time_cols(ctx, t_max):
    t = _time(ctx)
    cols, names = [], []
    for label, x in _decays(t, t_max, "t", "T", TAUS):
        cols += _scaled(ctx.pred, x)
        names += [f"{c} scaled by {label} (t: cycles since power-on, T = {t_max:.0f})"
                  for c in COMPONENTS]
    return cols, names


def _time_all(ctx, t_max):
    """The move scaled by the time terms, and the same terms added."""
    return _both_of(ctx, _decays(_time(ctx), t_max, "t", "T", TAUS),
                    f"t: cycles since power-on, T = {t_max:.0f}")


def _run_hypers(ctx, prob):
    return [max(float(ctx.batch.lengths.max()), 1.0)]


def _run_cols(ctx, n_max):
    """The move scaled and a term added, by powers of the cycles since the run's start and
    exp(-i / tau) (a warm-up at the start of every run, a cable winding up along it)."""
    i = np.broadcast_to(np.arange(ctx.batch.ids.shape[1], dtype=float)[None], ctx.batch.ids.shape)
    return _both_of(ctx, _decays(i, n_max, "i", "N", TAUS_RUN),
                    f"i: cycles since the run's start, N = {n_max:.0f}")


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


def _change_gaps(ctx, prob, w):
    """The best change points of :func:`_change_search`, each as the gap (lo, hi) between the
    fitting runs recorded just before and just after it."""
    c = np.sort(ctx.chron)
    out = []
    for at in _change_search(ctx, prob, w):
        k = int(np.searchsorted(c, at))
        out.append((float(c[k - 1]), float(c[k])))
    return out


def _after(chron: np.ndarray, gap) -> np.ndarray:
    """1 after the change, 0 before; a run recorded inside the gap, where the fitting runs
    cannot place the change, gets the chance that it came after (uniform over the gap)."""
    lo, hi = gap
    return np.clip((chron - lo) / max(hi - lo, 1e-12), 0.0, 1.0)


def _change_all(ctx, gap):
    after = np.broadcast_to(_after(ctx.chron, gap)[:, None], ctx.batch.ids.shape)
    return _both(ctx, np.asarray(after, float),
                 f"from {(gap[0] + gap[1]) / 2:.0%} of the recorded runs on")


def turn_direction(ids: np.ndarray) -> np.ndarray:
    """+1 on a right turn, -1 on a left turn, 0 on a straight gait cycle (strength 15)."""
    return np.where(strength(ids) == 15, 0, np.where(side(ids) == 0, 1, -1))


def reversal(ids: np.ndarray) -> np.ndarray:
    """True on the first gait cycle after the turn direction reverses (right to left or left
    to right, straight cycles between not counted as a reversal)."""
    d = turn_direction(ids)
    out = np.zeros(ids.shape, dtype=bool)
    out[..., 1:] = d[..., 1:] * d[..., :-1] < 0
    return out


def _previous_all(ctx, _):
    """The previous move added, and the first cycle after a reversal of the turn direction
    scaled and added to, and the previous turn's direction added."""
    cols, names = _previous_cols(ctx, None)
    rev = reversal(ctx.batch.ids).astype(float)
    c, n = _both(ctx, rev, "the first cycle after the turn direction reverses")
    prev = np.zeros(ctx.batch.ids.shape)
    prev[:, 1:] = turn_direction(ctx.batch.ids)[:, :-1]
    cols, names = (cols + c + _per_component(prev),
                   names + n + [f"previous turn's direction (+1 right, -1 left) added to {c}"
                                for c in COMPONENTS])
    k = since_change(ctx.batch.ids)
    for tau in SETTLE:
        c, n = _both(ctx, np.exp(-k / tau), f"exp(-k/{tau:.0f}) (k: cycles since the last "
                     "gait change)")
        cols, names = cols + c, names + n
    return cols, names


def since_change(ids: np.ndarray) -> np.ndarray:
    """Gait cycles since the last change of gait cycle: 0 on the first cycle after a change
    (and on a run's first), 1 on the next, ..."""
    k = np.zeros(ids.shape)
    for i in range(1, ids.shape[-1]):
        k[..., i] = np.where(ids[..., i] == ids[..., i - 1], k[..., i - 1] + 1, 0)
    return k


def _turn_mask(ids: np.ndarray, hyper) -> np.ndarray:
    sides, lo, hi = hyper
    s = strength(ids)
    on = (s >= lo) & (s < hi)
    if sides != "both":
        on &= side(ids) == (0 if sides == "right" else 1)
    return on.astype(float)


def turn_words(hyper) -> str:
    sides, lo, hi = hyper
    what = {"right": "right turns", "left": "left turns", "both": "turns"}[sides]
    if lo == 15:
        return "straight gait cycles" + ("" if sides == "both" else f" (id side {sides})")
    if (lo, hi) == (0, 15):
        return what
    return f"{what} of strength {lo}-{hi - 1}" if hi - lo > 1 else f"{what} of strength {lo}"


def _turn_cols(ctx, hyper):
    return _both(ctx, _turn_mask(ctx.batch.ids, hyper), f"on {turn_words(hyper)}")


def _turn_search(ctx, prob, w):
    """Every side (right, left, both) and band of turn strengths, from sums of the whitened
    columns of each gait cycle id; the best few go on to the stepwise fit. Bands that hold
    the same gait cycles of these runs are one: the widest is kept."""
    ids = ctx.batch.ids
    present = np.zeros(N_IDS, dtype=bool)
    present[np.unique(ids[ctx.batch.mask])] = True
    xw = _whiten_cols(prob, [c for g in range(N_IDS)
                             for c in _both(ctx, (ids == g).astype(float), "")[0]])
    k = xw.shape[1] // N_IDS
    per = xw.reshape(len(w), N_IDS, k)
    scored = {}
    for sides, gs in (("right", range(16)), ("left", range(16, 32)), ("both", range(32))):
        for lo in range(16):
            for hi in range(lo + 1, 15 + (lo == 15) + 1):  # turns, or straight alone
                sel = [g for g in gs if lo <= (g & 15) < hi and present[g]]
                if not sel:
                    continue
                key = tuple(sel)
                if key in scored and scored[key][1][2] - scored[key][1][1] >= hi - lo:
                    continue
                cols = per[:, sel].sum(axis=1)
                scored[key] = (_least_squares(cols, w)[1], (sides, lo, hi))
    best = sorted(scored.values(), key=lambda t: t[0])
    return [h for _, h in best[:3]]


def _previous_cols(ctx, _):
    prev = np.zeros(ctx.pred.shape)
    prev[:, 1:] = ctx.pred[:, :-1]
    cols, names = [], []
    for k, ck in enumerate(COMPONENTS):
        cols += _per_component(prev[..., k])
        names += [f"previous cycle's {ck} on {c}" for c in COMPONENTS]
    return cols, names


FAMILIES = (
    Family("periodic", _periodic_all, _periodic_hypers, n_hyper=1, search=_periodic_search),
    Family("heading", _heading_all, pose_dependent=True, test_columns=_heading_cols),
    Family("position", _position_all, pose_dependent=True, n_hyper=2,
           search=_position_search, test_columns=_position_bins,
           test_hypers=lambda ctx, prob: [None]),
    Family("time_since_power_on", _time_all, _time_hypers, test_columns=_time_cols),
    Family("sudden_change", _change_all, _change_hypers, n_hyper=1, search=_change_gaps,
           test_columns=_change_cols),
    Family("previous_gait_cycle", _previous_all, test_columns=_previous_cols),
    Family("turn", _turn_cols, n_hyper=2, search=_turn_search, shape_test=False),
    Family("time_in_run", _run_cols, _run_hypers, shape_test=False),
)
KIND_WORDS = {
    "periodic": "periodic in the cycle index", "heading": "dependent on heading",
    "position": "dependent on position", "time_since_power_on": "dependent on time since "
    "power-on", "sudden_change": "a sudden change in the recorded order of the runs",
    "previous_gait_cycle": "dependent on the previous gait cycle",
    "turn": "confined to one side or range of turns",
    "time_in_run": "dependent on the time since the run's start",
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


def _batched_ssr(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Residual sums of squares of y on each stack of columns x (m, n, k), as
    :func:`_least_squares` (the same tiny ridge)."""
    xt = np.swapaxes(x, 1, 2)
    a = xt @ x
    r = xt @ y
    tr = np.trace(a, axis1=1, axis2=2) / a.shape[1] + 1e-12
    a = a + 1e-10 * tr[:, None, None] * np.eye(a.shape[1])
    coef = np.linalg.solve(a, r[..., None])[..., 0]
    return float(y @ y) - np.einsum("mk,mk->m", r, coef)


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
    # held-out runs: whitened SSR before - after, per run (the paired comparison of families)
    run_gains: np.ndarray = field(default_factory=lambda: np.zeros(0))
    run_end_cm: np.ndarray = field(default_factory=lambda: np.zeros(0))  # rollout, per run
    # what predicts with it on new runs: the library effects it goes with, the fitted term
    base: tuple = ()
    chosen: tuple = ()
    coef: np.ndarray = field(default_factory=lambda: np.zeros(0))

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


def _hyper_json(hyper):
    """A family's hyper-parameter as JSON (a period, a change point, a band, a turn range)."""
    if hyper is None:
        return None
    if isinstance(hyper, tuple):
        return [v if isinstance(v, str) else (None if not math.isfinite(float(v))
                                              else round(float(v), 3)) for v in hyper]
    return round(float(hyper), 4)


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
        r = len(hold_p.batch.run_ids)
        run_gains = (w0.reshape(r, -1) ** 2).sum(axis=1) - (w1.reshape(r, -1) ** 2).sum(axis=1)
        prop = Proposal(fam.name, fam.name, terms, hyper, gain, float(w0 @ w0 - w1 @ w1), z,
                        min(1.0, p * len(FAMILIES)), float(shrink),
                        (float(end_model.mean()), float(end0.mean()), float(end1.mean())),
                        run_gains=run_gains, run_end_cm=end1, base=tuple(base),
                        chosen=tuple(chosen),
                        coef=np.asarray(coef, float))
        size = np.sqrt((delta[hold_p.batch.mask] ** 2).mean(axis=0)) / _sigma(noise)
        prop.extra = {"with_library_effects": [str(e) for e in base],
                      "replaces": [str(e) for e in effects if e not in base],
                      "acts_most_on": COMPONENTS[int(np.argmax(size))],
                      "hyper": _hyper_json(hyper)}
        prop.description = describe(prop, hold_p, hctx, fam, chosen, coef, noise)
        out.append(prop)
    out.sort(key=lambda q: -q.holdout_gain)
    mix = intermittent(fit_p, hold_p, noise)
    if mix is not None:  # the mixture's expected move, replayed on the model alone
        b = hold_p.batch
        body, world = step_moves(hold_p.rows, b.ids, hold_p.base_effects, b.n0)
        body = body * mix["expected_scale"] * b.mask[..., None]
        world = None if world is None else world * b.mask[..., None]
        end1 = _end_error(hold_p, integrate(b.poses[:, 0], body, world))
        mix["run_end_cm"] = end1
        mix["holdout"] = {
            "rollout_cm_model": round(float(end_model.mean()), 3),
            "rollout_cm_library": round(float(end0.mean()), 3),
            "rollout_cm_after": round(float(end1.mean()), 3),
            "shrink": round(1.0 - float(end1.sum() / end_model.sum()), 4)
            if end_model.sum() > 0 else 0.0,
            "shrink_over_library": round(1.0 - float(end1.sum() / end0.sum()), 4)
            if end0.sum() > 0 else 0.0}
    return out, mix


def _sigma(noise: NoiseFloor | None) -> np.ndarray:
    """The noise of one observed move per component (two poses' tracker noise and the step
    noise): what a correction's size is judged against."""
    if noise is None:
        return np.ones(3)
    pos = math.sqrt(2 * noise.pos_cm**2 + noise.step_cm**2)
    head = math.sqrt(2 * noise.heading_deg**2 + noise.step_deg**2)
    return np.maximum(np.array([pos, pos, head]), 1e-9)


def _form(names: Sequence[str], chosen: Sequence[int]) -> str:
    """Whether the chosen terms scale the move, add to it, or both."""
    scaled = any(" scaled " in names[k] for k in chosen)
    added = any(" scaled " not in names[k] for k in chosen)
    return {(True, False): "scales the move", (False, True): "adds a fixed amount",
            (True, True): "scales the move and adds to it"}.get((scaled, added), "")


def describe(prop: Proposal, prob: Problem, ctx: Context, fam: Family, chosen, coef,
             noise: NoiseFloor | None = None) -> str:
    """Words and numbers: what the term does, in the units of the moves, on the component
    where it is largest against the noise."""
    delta = _delta(fam, ctx, prop.hyper, chosen, coef)
    m = prob.batch.mask
    flat = delta[m]
    amp = np.sqrt(2.0) * np.sqrt((flat**2).mean(axis=0))  # a sine's amplitude from its rms
    j = int(np.argmax(amp / _sigma(noise)))
    unit = "deg" if j == 2 else "cm"
    what = KIND_WORDS[fam.name]
    names = fam.columns(ctx, prop.hyper)[1]
    form = _form(names, chosen)
    typical = ctx.pred[m].mean(axis=0) if m.any() else np.ones(3)
    if fam.name == "periodic":
        return (f"{what}, period about {prop.hyper:.1f} gait cycles, amplitude about "
                f"{amp[j]:.1f} {unit} on {COMPONENTS[j]} ({form})")
    if fam.name == "sudden_change":
        lo, hi = prop.hyper
        after = m & (_after(ctx.chron, prop.hyper) >= 1.0)[:, None]
        rel = _relative_change(ctx, delta, after)
        return (f"{what}: from {(lo + hi) / 2:.0%} of the runs on (between the runs at "
                f"{lo:.0%} and {hi:.0%} of the recorded order), the move is {rel} ({form})")
    if fam.name == "position" and prop.hyper[0] == "gradient":
        return f"{what}: {_gradient_words(prop, ctx, delta, chosen, coef, names)}"
    if fam.name == "position":
        axis, lo, hi = prop.hyper
        where = f"{lo:.0f} <= {'xy'[axis]} < {hi:.0f} cm".replace("-inf <= ", "").replace(
            " < inf cm", " cm and beyond")
        inside = (_band(ctx, axis, lo, hi) > 0) & m
        drift = _drift_words(chosen, coef, names, "world drift east", "world drift north")
        return (f"{what}: where {where} the move is {_relative_change(ctx, delta, inside)}"
                + (f"; {drift}" if drift else "") + f" ({form})")
    if fam.name in ("time_since_power_on", "time_in_run"):  # the term on a time line
        n = 301 if fam.name == "time_since_power_on" else max(int(prob.batch.lengths.max()), 2)
        marks = (0, 50, 150, 300) if n == 301 else (0, n // 8, n // 3, n - 1)
        line = Batch(("t",), np.zeros((1, n), dtype=np.int64), np.ones((1, n), dtype=bool),
                     np.zeros((1, n + 1, 3)), np.zeros(1, dtype=np.int64), np.array([n]))
        g = Context(line, np.broadcast_to(typical, (1, n, 3)).copy(), np.zeros((1, n, 3)),
                    ctx.chron)
        cols, _ = fam.columns(g, prop.hyper)
        d = sum(c * cols[k][0] for k, c in zip(chosen, coef, strict=True))
        scale = np.where(np.abs(typical) > 1e-9, np.abs(typical), np.inf)
        jj = int(np.argmax(np.abs(d).max(axis=0) / _sigma(noise)))
        u = "deg" if jj == 2 else "cm"
        return (f"{what}: {COMPONENTS[jj]} "
                + ", ".join(f"{d[t, jj] / scale[jj]:+.0%} at {t} cycles ({d[t, jj]:+.1f} {u})"
                            for t in marks)
                + f" of a typical move ({typical[jj]:.1f} {u}; {form})")
    if fam.name == "heading":
        grid = np.arange(0.0, 360.0, 5.0)
        g = Context(ctx.batch, np.broadcast_to(typical, (1, len(grid), 3)).copy(),
                    np.stack([np.zeros_like(grid), np.zeros_like(grid), grid], -1)[None], ctx.chron)
        cols, _ = fam.columns(g, prop.hyper)
        curve = sum(c * cols[k][0] for k, c in zip(chosen, coef, strict=True))
        k = int(np.argmax(np.abs(curve[:, j])))
        return (f"{what}: {COMPONENTS[j]} changes by up to {curve[k, j]:+.1f} {unit} per gait "
                f"cycle, most at heading {grid[k]:.0f} deg "
                f"(and {curve[(k + 36) % 72, j]:+.1f} at {grid[(k + 36) % 72]:.0f}; {form})")
    if fam.name == "turn":
        on = (_turn_mask(ctx.batch.ids, prop.hyper) > 0) & m
        n_on = int(on.sum())
        return (f"{what}: on {turn_words(prop.hyper)} ({n_on} of {int(m.sum())} gait cycles) "
                f"the move is {_relative_change(ctx, delta, on)}; elsewhere unchanged ({form})")
    if fam.name == "previous_gait_cycle":
        rev = reversal(ctx.batch.ids) & m
        parts = []
        if any("reverses" in names[k] for k in chosen) and rev.any():
            parts.append(f"on the first gait cycle after the turn direction reverses "
                         f"({int(rev.sum())} gait cycles) the move is "
                         f"{_relative_change(ctx, delta, rev)}")
        rest = [names[k] for k in chosen if "reverses" not in names[k]]
        if rest:
            size = float(np.abs(flat[:, j]).max())
            parts.append(f"up to {size:.1f} {unit} on {COMPONENTS[j]} ({rest[0]}"
                         + (", ..." if len(rest) > 1 else "") + ")")
        return f"{what}: " + "; ".join(parts)
    size = float(np.abs(flat[:, j]).max())
    return f"{what}: up to {size:.1f} {unit} on {COMPONENTS[j]} ({prop.terms[0]['term']}, ...)"


def _drift_words(chosen, coef, names, east: str, north: str) -> str:
    """A world-frame drift among the chosen terms, as a size and a direction."""
    v = np.zeros(2)
    for k, c in zip(chosen, coef, strict=True):
        if names[k].startswith(east):
            v[0] += c
        elif names[k].startswith(north):
            v[1] += c
    size = float(np.hypot(*v))
    if size < 1e-6:
        return ""
    toward = math.degrees(math.atan2(v[0], v[1])) % 360.0
    return f"a drift of {size:.2f} cm per gait cycle toward heading {toward:.0f} deg"


def _gradient_words(prop, ctx, delta, chosen, coef, names) -> str:
    """A drift or scale that grows across the floor: its size at the visited extremes, and
    the point it pulls toward when it converges."""
    m = ctx.batch.mask
    _, xc, yc = prop.hyper
    c0 = np.zeros(2)
    grad = np.zeros((2, 2))  # d drift / d (x, y), per metre
    for k, c in zip(chosen, coef, strict=True):
        n = names[k]
        if not n.startswith("world drift"):
            continue
        d = 0 if "east" in n else 1
        if "(x -" in n:
            grad[d, 0] += c
        elif "(y -" in n:
            grad[d, 1] += c
        else:
            c0[d] += c
    xs, ys = ctx.poses[..., 0][m], ctx.poses[..., 1][m]
    pts = [(float(np.quantile(xs, q)), float(np.quantile(ys, r)))
           for q, r in ((0.05, 0.05), (0.95, 0.95), (0.05, 0.95), (0.95, 0.05))]
    parts = []
    for x, y in pts:
        v = c0 + grad @ np.array([(x - xc) / 100.0, (y - yc) / 100.0])
        size = float(np.hypot(*v))
        if size >= 0.05:
            parts.append(f"{size:.2f} cm per gait cycle toward heading "
                         f"{math.degrees(math.atan2(v[0], v[1])) % 360:.0f} deg at "
                         f"({x:.0f}, {y:.0f}) cm")
    text = "a world drift that changes across the floor: " + ("; ".join(parts) or "small")
    ev = np.linalg.eigvals(grad)
    if np.all(ev.real < 0) and abs(np.linalg.det(grad)) > 1e-9:
        at = np.array([xc, yc]) - 100.0 * np.linalg.solve(grad, c0)
        text += (f" (it pulls toward about ({at[0]:.0f}, {at[1]:.0f}) cm, "
                 f"{-float(ev.real.mean()):.2f} cm per gait cycle per metre away)")
    rel = _relative_change(ctx, delta, m)
    if any(" scaled " in names[k] for k in chosen):
        text += f"; the move also changes with position (on average {rel})"
    return text


def _relative_change(ctx: Context, delta: np.ndarray, where: np.ndarray) -> str:
    """The correction on the steps ``where`` as a share of the model's move and in the moves'
    units (mean per gait cycle), per component."""
    pred, d = ctx.pred[where], delta[where]
    parts = []
    for j, c in enumerate(COMPONENTS):
        scale = np.abs(pred[:, j]).sum()
        if scale > 0 and len(d):
            r = float((d[:, j] * np.sign(pred[:, j])).sum() / scale)
            mean = float(d[:, j].mean())
            if abs(r) >= 0.01:
                parts.append(f"{c} {r:+.0%} ({mean:+.1f} {'deg' if j == 2 else 'cm'})")
    return ", ".join(parts) or "unchanged"


# --- intermittent: a mixture of per-step scales --------------------------------------------

def _scales(prob: Problem, noise: NoiseFloor, runs: bool = False):
    """Per step: the observed move's scale against the model's own (F, T) and its variance
    (and, with ``runs``, the run each step belongs to)."""
    b = prob.batch
    base = predicted_moves(prob.rows, b, tuple(prob.base_effects))
    ft = base[..., :2]
    n2 = (ft**2).sum(axis=-1)
    ok = b.mask & (np.sqrt(n2) >= MIN_MOVE_CM)
    rho = (b.observed[..., :2] * ft).sum(axis=-1) / np.where(ok, n2, 1.0)
    var = (2 * noise.pos_cm**2 + noise.step_cm**2
           + (np.radians(noise.heading_deg) ** 2) * n2) / np.where(ok, n2, 1.0)
    if runs:
        return rho[ok], var[ok], np.nonzero(ok)[0]
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
    xh, vh, run = _scales(hold_p, noise, runs=True)
    if len(x) < 40 or len(xh) < 10:
        return None
    m0 = float(np.average(x, weights=1 / v))
    tau0 = max(float(np.mean((x - m0) ** 2 - v)), 1e-6)
    ps, ms, tau2 = _em(x, v)
    per_step = _loglik(xh, vh, ps, ms, tau2) - _loglik(xh, vh, [1.0], [m0], tau0)
    gain = float(per_step.sum())
    run_gains = np.bincount(run, weights=per_step, minlength=len(hold_p.batch.run_ids))
    major = int(np.argmax(ps))
    minor = 1 - major
    return {"share": float(ps[minor]), "scale_minor": float(ms[minor]),
            "scale_major": float(ms[major]), "spread": float(np.sqrt(tau2)),
            "holdout_loglik_gain": gain, "expected_scale": float((ps * ms).sum()),
            "run_gains": run_gains,
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
    n = prob.n_obs  # not len(w): a shorter run's padded steps whiten to zeros
    out = {}
    for fam in FAMILIES:
        if fam.name == "periodic" or not fam.shape_test:  # the periodogram tests periodic
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
