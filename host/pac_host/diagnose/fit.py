"""Fit effects of the library to observed runs by maximum likelihood.

The objective is the whitened one-step residual sum of squares (:mod:`.likelihood`): a Gaussian
likelihood whose covariance is the one tracker noise on both ends of each step really gives.
Predictions always come from :func:`pac_host.model.effects.step_moves`, the same code that moves
the simulated world, so an effect is never re-implemented here; this module only searches its
parameters.

- Continuous parameters: ``scipy.optimize.least_squares`` (bounded trust region, ``dogbox``,
  which frees a parameter that starts on its bound where ``trf`` stalls) on the whitened
  residual vector, Jacobian by finite differences, parameters kept inside the
  bounds of :data:`EFFECT_SPECS`. Most effects are linear in their parameter on the residuals,
  so it converges in a few steps. ``floor_slope`` is searched as the world-frame drift vector
  (u, v) = s (sin theta, cos theta), where it is linear, and reported as (s, theta).
- Integer parameters (``turn_shift`` k): every k in its range is scored with the other
  parameters fixed, then the three best are refined jointly and the best kept.
- Intervals: from the curvature, ``cov = s^2 (J^T J)^-1`` with s^2 the whitened residual
  variance (so a wrong noise scale does not make intervals over-confident), mapped to the
  reported parameters by the delta method; for k, the set of k whose likelihood-ratio to the
  best is below the 95% chi-square(1) quantile.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2

from pac_host.diagnose.likelihood import Whitener
from pac_host.diagnose.residuals import Batch, step_residuals
from pac_host.model.effects import EFFECT_SPECS, Effect

CHI2_1_95 = float(chi2.ppf(0.95, 1))
FTOL = 1e-10  # relative change of the sum of squares (and of theta) that ends the search
MAX_NFEV = 60
TOP_INTEGERS = 3


@dataclass(frozen=True)
class Problem:
    """What fitting needs: the model's rows and own effects, the runs and their whitener.

    Two optional parts serve rows that were themselves fitted to noisy steps
    (:mod:`.fitted_rows`): ``rows_for`` gives the rows that go with the effects being tried
    (rows re-fitted beside them), and ``correlated`` = (U, f), U (n, k) orthonormal, maps a
    whitened residual w to ``w - U (f * U^T w)``: f = 1 takes a direction out (a parameter
    fitted beside the effects), 0 < f < 1 whitens noise correlated along it. ``dof_taken``:
    the observations the directions with f = 1 use up."""

    rows: np.ndarray
    base_effects: tuple[Effect, ...]
    batch: Batch
    whitener: Whitener
    rows_for: Callable[[tuple[Effect, ...]], np.ndarray] | None = None
    correlated: tuple[np.ndarray, np.ndarray] | None = None
    dof_taken: int = 0

    def _whitened_runs(self, effects: Sequence[Effect]) -> np.ndarray:
        effects = tuple(effects)
        rows = self.rows if self.rows_for is None else self.rows_for(effects)
        res = step_residuals(rows, self.batch, tuple(self.base_effects) + effects)
        w = self.whitener.whiten(res)
        if self.correlated is None:
            return w
        u, f = self.correlated
        flat = w.ravel()
        return (flat - u @ (f * (u.T @ flat))).reshape(w.shape)

    def whitened(self, effects: Sequence[Effect]) -> np.ndarray:
        return self._whitened_runs(effects).ravel()

    def ssr_per_run(self, effects: Sequence[Effect]) -> np.ndarray:
        w = self._whitened_runs(effects)
        return np.einsum("...i,...i->...", w, w)

    @property
    def n_obs(self) -> int:
        return 3 * self.batch.n_steps - self.dof_taken


# --- parameterization: internal continuous vector <-> Effect --------------------------------

def _continuous(name: str) -> list:
    spec = EFFECT_SPECS[name]
    if name == "floor_slope":
        return [("u", -20.0, 20.0), ("v", -20.0, 20.0)]
    return [(p.name, p.lo, p.hi) for p in spec.params if not p.integer]


def _integer(name: str) -> list:
    return [p for p in EFFECT_SPECS[name].params if p.integer]


def n_params(name: str) -> int:
    """Degrees of freedom an effect adds (an integer parameter counts as one)."""
    return len(EFFECT_SPECS[name].params)


def to_internal(effect: Effect) -> list[float]:
    p = effect.params
    if effect.name == "floor_slope":
        th = math.radians(p["theta"])
        return [p["s"] * math.sin(th), p["s"] * math.cos(th)]
    return [float(p[n]) for n, _, _ in _continuous(effect.name)]


def from_internal(name: str, values: Sequence[float], ints: dict | None = None) -> Effect:
    if name == "floor_slope":
        u, v = values
        s = min(math.hypot(u, v), 20.0)
        theta = math.degrees(math.atan2(u, v)) if s > 0 else 0.0
        return Effect(name, {"s": s, "theta": theta})
    params = {n: float(np.clip(x, lo, hi)) for (n, lo, hi), x in zip(_continuous(name), values,
                                                                     strict=True)}
    params.update(ints or {})
    return Effect(name, params)


def neutral(name: str) -> Effect:
    return Effect(name, {p.name: p.neutral for p in EFFECT_SPECS[name].params})


# --- the fit ---------------------------------------------------------------------------------

@dataclass
class FitResult:
    effects: list[Effect]
    ssr: float
    n_obs: int
    df: int
    intervals: dict = field(default_factory=dict)  # effect name -> {param: [lo, hi]}
    iterations: int = 0  # evaluations of the residual in the search

    @property
    def sigma2(self) -> float:
        return self.ssr / max(self.n_obs - self.df, 1)


class _Layout:
    """Where each effect's continuous parameters sit in one vector."""

    def __init__(self, names: Sequence[str]):
        self.names = list(names)
        self.slices = []
        lo, hi = [], []
        k = 0
        for n in self.names:
            c = _continuous(n)
            self.slices.append(slice(k, k + len(c)))
            lo += [b[1] for b in c]
            hi += [b[2] for b in c]
            k += len(c)
        self.lo, self.hi = np.array(lo), np.array(hi)
        self.size = k

    def effects(self, theta: np.ndarray, ints: dict) -> list[Effect]:
        return [from_internal(n, theta[s], ints.get(n)) for n, s in zip(self.names, self.slices,
                                                                        strict=True)]

    def theta(self, effects: dict[str, Effect]) -> np.ndarray:
        out = np.empty(self.size)
        for n, s in zip(self.names, self.slices, strict=True):
            out[s] = to_internal(effects.get(n) or neutral(n))
        return np.clip(out, self.lo, self.hi)


def _solve(prob: Problem, lay: _Layout, theta: np.ndarray, ints: dict):
    """Least squares over the continuous parameters within their bounds (SciPy's dogbox
    trust region, Jacobian by finite differences). Returns (theta, ssr, jacobian, nfev)."""
    def f(t: np.ndarray) -> np.ndarray:
        return prob.whitened(lay.effects(t, ints))

    if lay.size == 0:
        r = f(theta)
        return theta, float(r @ r), np.empty((r.size, 0)), 1
    res = least_squares(f, theta, bounds=(lay.lo, lay.hi), method="dogbox", x_scale="jac",
                        ftol=FTOL, xtol=FTOL, gtol=FTOL, max_nfev=MAX_NFEV)
    return res.x, float(res.fun @ res.fun), res.jac, res.nfev


def fit_effects(prob: Problem, names: Sequence[str], start: dict[str, Effect] | None = None
                ) -> FitResult:
    """Jointly fit the effects ``names`` (from ``start`` values, else neutral) on ``prob``."""
    start = dict(start or {})
    lay = _Layout(names)
    theta0 = lay.theta(start)
    int_names = [n for n in names if _integer(n)]
    if len(int_names) > 1:
        raise ValueError("at most one effect with an integer parameter per fit")
    if int_names:
        n = int_names[0]
        p = _integer(n)[0]
        values = range(int(p.lo), int(p.hi) + 1)
        scored = []
        for v in values:
            ints = {n: {p.name: v}}
            f = prob.whitened(lay.effects(theta0, ints))
            scored.append((float(f @ f), v))
        scored.sort()
        best = None
        for _, v in scored[:TOP_INTEGERS]:
            ints = {n: {p.name: v}}
            theta, ssr, jac, it = _solve(prob, lay, theta0, ints)
            if best is None or ssr < best[1]:
                best = (theta, ssr, jac, it, ints)
        theta, ssr, jac, it, ints = best
        # the profile over k with the other parameters at their optimum
        prof = {}
        for v in values:
            f = prob.whitened(lay.effects(theta, {n: {p.name: v}}))
            prof[v] = float(f @ f)
    else:
        ints = {}
        theta, ssr, jac, it = _solve(prob, lay, theta0, ints)
        prof = None
    effects = lay.effects(theta, ints)
    df = sum(n_params(n) for n in names)
    res = FitResult(effects, ssr, prob.n_obs, df, iterations=it)
    res.intervals = _intervals(lay, theta, jac, ints, res, prof)
    return res


def _intervals(lay: _Layout, theta: np.ndarray, jac: np.ndarray, ints: dict, res: FitResult,
               prof: dict | None) -> dict:
    out: dict = {}
    s2 = res.sigma2
    if lay.size:
        try:
            cov = s2 * np.linalg.inv(jac.T @ jac)
        except np.linalg.LinAlgError:  # a parameter the data do not constrain
            cov = np.full((lay.size, lay.size), np.nan)
        for n, sl, e in zip(lay.names, lay.slices, res.effects, strict=True):
            c = cov[sl, sl]
            if not np.all(np.isfinite(c)):
                sd = {name: math.nan for name in e.params}
            elif n == "floor_slope":
                u, v = theta[sl]
                s = math.hypot(u, v) or 1e-12
                g_s = np.array([u / s, v / s])
                g_t = np.degrees(np.array([v / s**2, -u / s**2]))
                sd = {"s": math.sqrt(max(g_s @ c @ g_s, 0)),
                      "theta": math.sqrt(max(g_t @ c @ g_t, 0))}
            else:
                sd = {name: math.sqrt(max(c[j, j], 0))
                      for j, (name, _, _) in enumerate(_continuous(n))}
            out[n] = {k: [round(e.params[k] - 1.96 * v, 6), round(e.params[k] + 1.96 * v, 6)]
                      for k, v in sd.items()}
    if prof is not None:
        n = next(iter(ints))
        pname = next(iter(ints[n]))
        ok = [v for v, s in prof.items() if (s - res.ssr) / s2 < CHI2_1_95]
        out.setdefault(n, {})[pname] = [min(ok), max(ok)]
    return out
