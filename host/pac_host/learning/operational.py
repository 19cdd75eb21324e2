"""The operational turn cycle on a noisy robot: chosen on the evidence of all its walks.

A robot with step noise walks a turn cycle differently every time, so one walk is one draw:
replacing the operational turn cycle whenever one walk beats the last keeps the luckiest walk
(the winner's curse). With ``operational_evidence`` and step noise estimated clearly above
zero (:func:`pac_host.diagnose.noise.estimate_step_noise`), each candidate's expected fitness
is the mean of its walks shrunk toward the model's prediction (:func:`estimate`): the model,
walked :data:`MODEL_WALKS` times with the estimated noise, gives the prediction and the
spread of one walk. How much the prediction counts is learnt from the model's track record
(:func:`model_error_var`): the walked turn cycles' means against the model's predictions,
beyond what their walks' own spread explains. A model whose predictions have held counts as
many walks, one that has missed counts as few; before :data:`MIN_TRACK` turn cycles have been
walked it counts as one walk at most (less where its population disagrees). A challenger
replaces the operational turn cycle only when its estimate is higher by more than
:data:`DECISION_Z` standard errors of the difference; higher but not by that much, the one
known less well is walked again at the next punctuation; with no challenger higher but one
not clearly lower, the operational one until it has :data:`CONFIRM_WALKS` walks, and then
again the one known less well (:func:`decide`): a turn cycle made operational by its walks is
the luckiest of those tested until fresh walks say otherwise, and a race too close to call
goes on until it is called. Without step noise a walk is exact and the rule is the paper's:
the higher walk wins.

>>> e = estimate([45], predicted=15.0, walk_sd=10.0, model_sd=0.0)
>>> round(e.mean, 1), e.walks
(30.0, 1)
>>> estimate([20, 22], predicted=0.0, walk_sd=0.0, model_sd=5.0).to_json()
{'mean': 21.0, 'interval': [21.0, 21.0], 'walks': 2}
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.coverage import format_turn_cycle, simulate
from pac_host.diagnose.noise import Z95
from pac_host.model.effects import Effect
from pac_host.model.step_noise import StepNoise

MODEL_WALKS = 512  # noisy walks of the model per candidate: its prediction and a walk's spread
MIN_TRACK = 3  # walked turn cycles before the model's track record sets its weight
# a challenger must beat the operational one by this many standard errors of the difference:
# with a model that counts as one walk at most (no track record yet), a one-sided 95% margin
# keeps a single lucky walk out; once the model's weight is learnt from its track record the
# estimates are shrunk for luck as far as the record shows, and one standard error guards
# against flip-flops without holding on to a worse sweep (at 1.645 a sweep 2 blocks better
# was not confirmed in 14 punctuations at 0.3 cm / 1 deg: docs/results.md)
DECISION_Z = 1.645
TRACKED_Z = 1.0
# an operational turn cycle is walked again while a challenger is not clearly worse, until it
# has this many walks (then the two take turns, the one known less well first): it became
# operational on walks that beat the others', so its early mean
# is the lucky one, and a walk's fitness is skewed (a sweep of mean 24 walks 32 or more three
# times in ten): on the noisy shifted robot a run held a sweep of 22 for 20 punctuations on
# three walks that averaged 28 (docs/explanation/learning.md, "PAL on a noisy robot")
CONFIRM_WALKS = 8


@dataclass(frozen=True)
class Estimate:
    """A turn cycle's expected fitness on the robot: mean, standard error, walks behind it."""

    mean: float
    sd: float
    walks: int

    def interval(self) -> tuple[float, float]:
        """The 95% interval of the expectation."""
        return self.mean - Z95 * self.sd, self.mean + Z95 * self.sd

    def to_json(self) -> dict:
        lo, hi = self.interval()
        return {"mean": round(self.mean, 2), "interval": [round(lo, 2), round(hi, 2)],
                "walks": self.walks}


def key(turn_cycle: np.ndarray) -> str:
    """The name walks are kept under: the turn cycle's text form."""
    return format_turn_cycle(turn_cycle)


def estimate(walks: Sequence[float], predicted: float, walk_sd: float, model_sd: float,
             error_var: float | None = None) -> Estimate:
    """The expected fitness of a turn cycle from its ``walks`` on the robot and the model's
    ``predicted`` expectation: the walks' mean shrunk toward the prediction (a Gaussian
    posterior; ``walk_sd`` the spread of one walk). The prediction's own variance is
    ``error_var`` (the model's error learnt from its track record, :func:`model_error_var`)
    plus ``model_sd^2`` (its population's disagreement) and the Monte Carlo error of its
    :data:`MODEL_WALKS` walks; without a track record (``error_var`` None) ``walk_sd^2 +
    model_sd^2``, so the model counts as one walk at most. ``walk_sd`` 0: the walks are exact
    (their mean, no spread); no walks: the prediction.

    >>> round(estimate([30], 20.0, 10.0, 0.0, error_var=1.0).mean, 1)  # a model that has held
    20.1
    """
    n = len(walks)
    if walk_sd <= 0.0:
        if n:
            return Estimate(float(np.mean(walks)), 0.0, n)
        return Estimate(float(predicted), float(model_sd), 0)
    prior_var = (walk_sd**2 + model_sd**2 if error_var is None
                 else error_var + model_sd**2 + walk_sd**2 / MODEL_WALKS)
    precision = 1.0 / prior_var + n / walk_sd**2
    mean = (predicted / prior_var + float(np.sum(walks)) / walk_sd**2) / precision
    return Estimate(float(mean), math.sqrt(1.0 / precision), n)


def model_walks(models: np.ndarray, effects: Sequence[Effect], candidates: np.ndarray,
                budget: int, noise: StepNoise, rng: np.random.Generator,
                walks: int = MODEL_WALKS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each candidate (C, 9, 2): the model's expected fitness and one walk's standard
    deviation over ``walks`` noisy walks of the model (``models[0]``) with ``noise``, and the
    standard deviation of the noise-free fitness over the model population (its
    disagreement), each (C,). The candidates share the walks' noise (common random numbers,
    the compiled kernel): their predictions differ by their turn cycles, not by their draws."""
    from pac_host.coverage.noisy import NoisyWalks, draw_normals

    z = draw_normals(rng, walks, budget)
    fit = NoisyWalks(models[0], noise, z, budget, effects).figures(candidates)[2]
    fit = fit.astype(np.float64)
    spread = simulate(models, candidates, budget, effects).fitness.astype(np.float64)
    return fit.mean(axis=1), fit.std(axis=1, ddof=1), spread.std(axis=0)


def model_error_var(walks: dict[str, Sequence[float]], predicted: dict[str, float],
                    walk_sd: dict[str, float], leave_out: str | None = None) -> float | None:
    """The variance of the model's prediction error from its track record: over every walked
    turn cycle it predicts, the squared gap between its walks' mean and the prediction less
    what the walks' spread alone gives (``walk_sd^2 / n`` and the prediction's Monte Carlo
    error), averaged (an unbiased estimate of the error's variance), at least 0; None with
    fewer than :data:`MIN_TRACK` such turn cycles. ``leave_out``: the record without that turn
    cycle, for weighing the model's prediction of it: its own walks are already the evidence
    against the prediction, and counted again in the model's error a run of luck would make
    the model that predicted it rightly count for less (cross-validated empirical Bayes).

    >>> model_error_var({"a": [20, 22], "b": [30], "c": [10]},
    ...                 {"a": 21.0, "b": 30.0, "c": 10.0}, {"a": 2.0, "b": 2.0, "c": 2.0})
    0.0
    >>> model_error_var({"a": [20]}, {"a": 10.0}, {"a": 2.0}) is None
    True
    >>> model_error_var({"a": [20], "b": [30], "c": [10], "lucky": [40]},
    ...                 {"a": 20.0, "b": 30.0, "c": 10.0, "lucky": 20.0},
    ...                 dict.fromkeys(["a", "b", "c", "lucky"], 2.0), leave_out="lucky")
    0.0
    """
    terms = [(float(np.mean(w)) - predicted[k]) ** 2
             - walk_sd[k] ** 2 * (1.0 / len(w) + 1.0 / MODEL_WALKS)
             for k, w in walks.items() if len(w) and k in predicted and k != leave_out]
    if len(terms) < MIN_TRACK:
        return None
    return max(0.0, float(np.mean(terms)))


def pooled_sd(model_sd: float, walks: Sequence[float], model_walks_n: int = MODEL_WALKS
              ) -> float:
    """One walk's spread: the model's walks' and the robot's own walks' pooled."""
    n = len(walks)
    if n < 2:
        return model_sd
    ss = (model_walks_n - 1) * model_sd**2 + (n - 1) * float(np.var(walks, ddof=1))
    return math.sqrt(ss / (model_walks_n + n - 2))


def with_repeat(tests: np.ndarray, repeat: np.ndarray | None) -> np.ndarray:
    """``tests`` (T, 9, 2) with ``repeat`` in the last place (test 0, the best on the model,
    stays), unless it is tested already or None."""
    if repeat is None or any(np.array_equal(t, repeat) for t in tests) or len(tests) < 2:
        return tests
    out = tests.copy()
    out[-1] = repeat
    return out


def decide(operational: str | None, estimates: dict[str, Estimate],
           challengers: Sequence[str], z: float = DECISION_Z) -> tuple[str | None, str | None]:
    """(the candidate that becomes operational or None to keep it, the candidate to walk
    again or None): the ``challengers`` (tested keys) with the highest expectation against the
    ``operational`` one (None: none yet, the best challenger is taken). It replaces only when
    higher by more than ``z`` standard errors of the difference (:data:`DECISION_Z`, or
    :data:`TRACKED_Z` once the model's weight comes from its track record); higher by less,
    the one of the two with the larger standard error is walked again; lower by less, the
    operational one while it has fewer than :data:`CONFIRM_WALKS` walks, and after that again
    the one with the larger standard error: with a cap on its walks, a lucky run of walks
    would keep a worse operational turn cycle for good.

    >>> est = {"a": Estimate(15.0, 1.0, 6), "b": Estimate(20.0, 6.0, 1)}
    >>> decide("a", est, ["b"]), decide("a", {**est, "b": Estimate(25.0, 2.0, 3)}, ["b"])
    ((None, 'b'), ('b', None))
    >>> decide("a", {"a": Estimate(26.0, 2.0, 3), "b": Estimate(25.0, 2.0, 2)}, ["b"])
    (None, 'a')
    >>> decide("a", {"a": Estimate(26.0, 2.0, 9), "b": Estimate(25.0, 2.5, 4)}, ["b"])
    (None, 'b')
    """
    others = [c for c in challengers if c != operational]
    if not others:
        return None, None
    best = max(others, key=lambda c: estimates[c].mean)  # first of equals: the earlier test
    if operational is None:
        return best, None
    o, c = estimates[operational], estimates[best]
    gap = c.mean - o.mean
    if gap > z * math.hypot(o.sd, c.sd):
        return best, None
    if gap <= -z * math.hypot(o.sd, c.sd):
        return None, None
    if gap <= 0 and o.walks < CONFIRM_WALKS:
        return None, operational
    # too close to call: the one known less well, however many walks the operational one has
    return None, best if c.sd > o.sd else operational
