"""The residual's shape: what white Gaussian noise on poses and steps cannot produce.

The structure test of :mod:`.select` asks whether flexible forms of the library's kind (an
offset per gait cycle, a drift with time, ...) still fit the residual. An effect of another
kind passes it: a stall on a random 15% of gait cycles, a heading wobble, a change of payload
halfway. Such effects also leak into the noise floor (a stall inside a segment of repeats
looks like step noise), so the residual's size against the floor does not show them either.
Their residuals have a shape noise does not have, tested here on the whitened one-step
innovations (:mod:`.likelihood`), which are independent standard normal under the noise
model whatever its scale:

- ``tails``: skewness and kurtosis (D'Agostino's K^2, ``scipy.stats.normaltest``) per
  component: a share of gait cycles that move far less (or more) than the rest;
- ``periodogram``: the periodogram summed over runs, each frequency against the local median
  of its neighbours (gamma tail): a periodic term in the cycle index;
- ``autocorrelation``: Ljung-Box over lags 2..10 pooled over runs: slow structure along a run
  (reported, not a flag: with thousands of steps it also sees the small misfit of the noise
  model itself; 6 of 28 effect-free or explained cases failed it at the flag's level);
- ``dependence``: F-tests of families of candidate terms (:mod:`.propose`): position,
  heading, time since power-on, the previous gait cycle, a change in the recorded order;
- ``noise_floor``: step noise implausibly large against the moves (a real robot's own
  step-to-step variation is a few percent of its stride).

Each p-value is Bonferroni-corrected for the number of tests; any below :data:`SHAPE_ALPHA`
makes the verdict ``partly_unexplained``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from pac_host.diagnose.fit import Problem
from pac_host.diagnose.noise import NoiseFloor
from pac_host.diagnose.residuals import step_residuals
from pac_host.model.effects import Effect
from pac_host.model.table import COMPONENTS

SHAPE_ALPHA = 1e-4
INFORMATIVE_ONLY = frozenset({"autocorrelation"})
LAGS = range(2, 11)
MAX_PERIOD = 30.0
WINDOW = 6  # periodogram points on each side for the local median
STEP_SHARE = 0.15  # step noise above this share of the median move is implausible
MIN_STEPS = 40


@dataclass
class ShapeTest:
    name: str
    kind: str  # what an effect that fails it is: intermittent, periodic, heading, ...
    p_value: float  # Bonferroni-corrected
    statistic: float
    description: str

    def to_json(self) -> dict:
        return {"test": self.name, "kind": self.kind, "p_value": float(self.p_value),
                "statistic": round(float(self.statistic), 3), "description": self.description}


def innovations(prob: Problem, effects: Sequence[Effect]) -> tuple[np.ndarray, np.ndarray]:
    """Whitened one-step innovations (R, N, 3) of the model plus ``effects`` and the mask."""
    b = prob.batch
    res = step_residuals(prob.rows, b, tuple(prob.base_effects) + tuple(effects))
    w = prob.whitener.whiten(res)
    r, n = b.mask.shape
    e = w.reshape(r, -1, 3)[:, :n] * b.mask[..., None]
    return e, b.mask


def tails_test(e: np.ndarray, mask: np.ndarray) -> tuple[float, float, int]:
    """(p, statistic, component) of the normality test of the worst component."""
    flat = e[mask]
    if len(flat) < MIN_STEPS:
        return 1.0, 0.0, 0
    best = (1.0, 0.0, 0)
    for j in range(3):
        stat, p = sps.normaltest(flat[:, j])
        if p < best[0]:
            best = (float(p), float(stat), j)
    return min(1.0, best[0] * 3), best[1], best[2]


def summed_periodogram(x: np.ndarray, mask: np.ndarray, freqs: np.ndarray) -> np.ndarray:
    """Sum over runs of |sum_i x_i exp(-2 pi i f i)|^2 / n_r at each frequency (F,)."""
    i = np.arange(x.shape[1])
    basis = np.exp(-2j * np.pi * np.outer(i, freqs))  # (N, F)
    n = np.maximum(mask.sum(axis=1), 1)
    return ((np.abs((x * mask) @ basis) ** 2) / n[:, None]).sum(axis=0)


def frequency_grid(n: int) -> np.ndarray:
    """Frequencies (cycles per gait cycle) from period min(N/2, 30) down to about 2.2."""
    lo = 1.0 / min(n / 2.0, MAX_PERIOD)
    step = 1.0 / (2.0 * n)
    return np.arange(lo, 0.45 + 1e-12, step)


def periodogram_test(e: np.ndarray, mask: np.ndarray) -> tuple[float, float, float, int]:
    """(p, ratio, period, component) of the largest periodogram peak against its neighbours."""
    n_runs = int((mask.sum(axis=1) > 0).sum())
    freqs = frequency_grid(int(np.median(mask.sum(axis=1))))
    if len(freqs) < 2 * WINDOW + 1 or n_runs == 0 or mask.sum() < MIN_STEPS:
        return 1.0, 0.0, float("nan"), 0
    best = (1.0, 0.0, float("nan"), 0)
    med = sps.gamma.median(n_runs)
    for j in range(3):
        s = summed_periodogram(e[..., j], mask, freqs)
        pad = np.pad(s, WINDOW, mode="reflect")
        local = np.array([np.median(pad[k : k + 2 * WINDOW + 1]) for k in range(len(s))])
        ratio = s / np.maximum(local / med, 1e-12)
        k = int(np.argmax(ratio))
        p = float(sps.gamma.sf(ratio[k], n_runs))
        if p < best[0]:
            best = (p, float(ratio[k] / n_runs), float(1.0 / freqs[k]), j)
    p, ratio, period, j = best
    return min(1.0, p * 3 * len(freqs)), ratio, period, j


def ljung_box(e: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """(p, Q) of Ljung-Box over lags 2..10, pooled over runs and the three components."""
    x = e * mask[..., None]
    total = float((x**2).sum())
    n = float(mask.sum())
    if total <= 0 or n < MIN_STEPS:
        return 1.0, 0.0
    q = 0.0
    for k in LAGS:
        both = mask[:, k:] & mask[:, :-k]
        for j in range(3):
            rho = float((x[:, k:, j] * x[:, :-k, j] * both).sum()) / (total / 3)
            q += n * (n + 2) / max(n - k, 1) * rho**2
    return float(sps.chi2.sf(q, 3 * len(LAGS))), q


def noise_floor_check(noise: NoiseFloor, moves: np.ndarray, mask: np.ndarray
                      ) -> ShapeTest | None:
    """Step noise that is a large share of the model's moves: an effect leaked into it."""
    ft = np.hypot(moves[..., 0], moves[..., 1])[mask]
    if not len(ft):
        return None
    med = float(np.median(ft))
    if med > 0 and noise.step_cm > STEP_SHARE * med:
        return ShapeTest("noise_floor", "noise_floor", 0.0, noise.step_cm / med,
                         f"implausible noise floor: step noise {noise.step_cm:.2f} cm is "
                         f"{noise.step_cm / med:.0%} of the median move ({med:.1f} cm); "
                         "an effect on single gait cycles is likely mistaken for noise")
    return None


def shape_tests(prob: Problem, effects: Sequence[Effect], noise: NoiseFloor,
                families: dict | None = None) -> list[ShapeTest]:
    """All shape tests on ``prob``'s runs with the model plus ``effects``; ``families``:
    name -> (kind, p, statistic, description) of the dependence F-tests (:mod:`.propose`)."""
    e, mask = innovations(prob, effects)
    families = families or {}
    n_tests = 3 + len(families)
    out = []
    p, stat, j = tails_test(e, mask)
    out.append(ShapeTest("tails", "intermittent", min(1.0, p * n_tests), stat,
                         f"{COMPONENTS[j]} residuals are not Gaussian (K^2 = {stat:.0f}): "
                         "a share of gait cycles moves unlike the rest"))
    p, ratio, period, j = periodogram_test(e, mask)
    out.append(ShapeTest("periodogram", "periodic", min(1.0, p * n_tests), ratio,
                         f"{COMPONENTS[j]} residuals have a periodogram peak "
                         f"{ratio:.1f} times its neighbours' at a period of {period:.1f} "
                         "gait cycles"))
    p, q = ljung_box(e, mask)
    out.append(ShapeTest("autocorrelation", "autocorrelated", min(1.0, p * n_tests), q,
                         f"residuals correlated over lags 2-10 (Ljung-Box Q = {q:.0f})"))
    for name, (kind, p, stat, text) in families.items():
        out.append(ShapeTest(name, kind, min(1.0, p * n_tests), stat, text))
    pred = prob.batch.observed - step_residuals(prob.rows, prob.batch,
                                                tuple(prob.base_effects) + tuple(effects))
    nf = noise_floor_check(noise, pred, mask)
    if nf is not None:
        out.append(nf)
    return out


def flagged(tests: Sequence[ShapeTest]) -> list[ShapeTest]:
    """The tests that fail, most significant first (the Ljung-Box test is only reported)."""
    return sorted((t for t in tests if t.p_value < SHAPE_ALPHA
                   and t.name not in INFORMATIVE_ONLY), key=lambda t: t.p_value)
