"""Beyond the library: rank the candidate explanations, say when the runs cannot tell them
apart, and propose the run that would.

Each family of :mod:`.propose` (and the intermittent mixture) is a candidate explanation with
a held-out log-likelihood gain per held-out run, and a held-out rollout end error per run. The
figures of two candidates on the same runs are paired: the leader's lead is the sum of the
per-run differences, its uncertainty their spread over the runs (a t interval, the runs taken
as exchangeable). The leader is clearly ahead when one measure's 95% interval of its lead
excludes zero and the other does not favour the runner-up; otherwise a runner-up gaining at
least half the leader's gain fits about as well: the kind is then ``ambiguous`` and the report
names them all instead of one.

To separate them, each candidate predicts a small set of possible test runs (one gait cycle
held for a run's length, or a turn and its mirror alternating; from four start headings;
right after power-on and late in a session), and the run whose predictions differ most
against the noise is proposed: the sum over its gait cycles of the symmetric Kullback-Leibler
divergence between the candidates' Gaussian predictions of each observed move (means and,
for the intermittent mixture, its extra variance), the smallest over the pairs of candidates.

:func:`where_summary` says where the residual the library leaves lies: its size against the
noise floor per component, and the contexts (first cycle after a gait change or after the
turn direction reverses, turn side and strength, time since power-on and since the run's
start, heading, position) where
it differs most from elsewhere, with the numbers.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats as sps

from pac_host.diagnose.fit import Problem
from pac_host.diagnose.noise import NoiseFloor
from pac_host.diagnose.propose import (
    FAMILIES,
    Proposal,
    _replay,
    _sigma,
    reversal,
)
from pac_host.diagnose.residuals import Batch, contexts
from pac_host.model.effects import step_moves
from pac_host.model.kinematics import integrate, moves_between
from pac_host.model.table import COMPONENTS, side, strength

LEVEL = 0.95
MAX_ALIKE = 4  # candidates named together at most (the leader and three)
# a runner-up fits about as well as the leader when the paired interval of the leader's lead
# reaches zero and it gains at least this share of the leader's gain
ALIKE_RATIO = 0.5
# below this share of the held-out excess over the noise floor the leader explains too
# little to name the kind (when the excess is positive: a noise floor that absorbed the
# effect leaves none to share)
MIN_SHARE = 0.5
DESIGN_IDS = (0, 7, 15, 16, 23)  # hardest and middle turns each way, straight
MIN_CONTEXT_STEPS = 5
MIN_CONTEXT_Z = 4.0


@dataclass
class Candidate:
    """One explanation: its kind, its held-out evidence and how it predicts a new run."""

    family: str
    kind: str
    description: str
    run_gains: np.ndarray  # held-out log-likelihood gain per held-out run (nats)
    shrink: float | None  # held-out rollout end-error shrink against the model alone
    # a batch of new runs -> (mean moves (R, N, 3), extra variance of each move (R, N, 3))
    predict: Callable[[Batch], tuple[np.ndarray, np.ndarray]]
    proposal: dict = field(default_factory=dict)
    run_end_cm: np.ndarray | None = None  # held-out rollout end error per run, cm

    @property
    def gain(self) -> float:
        return float(self.run_gains.sum())


def _t(n: int) -> float:
    return float(sps.t.ppf(0.5 + LEVEL / 2, max(n - 1, 1)))


def interval(g: np.ndarray) -> tuple[float, float]:
    """A t interval of the sum of per-run values (runs exchangeable)."""
    n = len(g)
    if n < 2:
        return (float(g.sum()), float(g.sum()))
    half = _t(n) * math.sqrt(n) * float(np.std(g, ddof=1))
    return (float(g.sum()) - half, float(g.sum()) + half)


def rank(cands: Sequence[Candidate], excess: float | None = None
         ) -> tuple[list[Candidate], list[dict], int]:
    """The candidates best first, each one's evidence (gain with its interval, the leader's
    lead over it, paired by run, and the share it takes of ``excess``, the held-out
    log-likelihood the noise floor leaves unexplained), and how many fit about as well as the
    leader (the leader counted)."""
    order = sorted(cands, key=lambda c: -c.gain)
    if not order:
        return [], [], 0
    top = order[0]
    rows, alike = [], 1
    for k, c in enumerate(order):
        lo, hi = interval(c.run_gains)
        row = {"rank": k + 1, "kind": c.kind, "family": c.family,
               "description": c.description,
               "holdout_loglik_gain": round(c.gain, 2),
               "gain_interval_95": [round(lo, 2), round(hi, 2)],
               "shrink": None if c.shrink is None else round(c.shrink, 4),
               "share_of_excess": round(c.gain / excess, 3) if excess and excess > 0 else None}
        if k:
            d = top.run_gains - c.run_gains
            dlo, dhi = interval(d)
            row["behind_leader"] = round(float(d.sum()), 2)
            row["behind_leader_interval_95"] = [round(dlo, 2), round(dhi, 2)]
            # the second held-out measure: whole runs replayed, end errors paired by run
            ahead_rollout = behind_rollout = False
            if top.run_end_cm is not None and c.run_end_cm is not None:
                e = c.run_end_cm - top.run_end_cm
                elo, ehi = interval(e)
                row["rollout_behind_leader_cm"] = round(float(e.mean()), 3)
                row["rollout_behind_leader_interval_95"] = [round(elo / len(e), 3),
                                                            round(ehi / len(e), 3)]
                ahead_rollout, behind_rollout = elo > 0.0, ehi < 0.0
            # clearly ahead: on one measure, and the other does not favour the runner-up
            clear = (dlo > 0.0 and not behind_rollout) or ahead_rollout
            row["alike_leader"] = (not clear and c.gain >= ALIKE_RATIO * top.gain
                                   and alike < MAX_ALIKE)
            alike += row["alike_leader"]
        rows.append(row)
    return order, rows, alike


# --- the run that would separate them -----------------------------------------------------

@dataclass(frozen=True)
class Design:
    words: str
    ids: np.ndarray  # (N,) gait cycle ids
    n0: int
    start: np.ndarray  # (3,) the start pose


def designs(batch: Batch) -> list[Design]:
    """Possible test runs, from where these runs start and how long and late they are."""
    m = batch.mask
    n = int(np.clip(np.median(batch.lengths), 20, 100))
    start = np.median(batch.poses[:, 0], axis=0)
    since = batch.n0[:, None] + np.arange(batch.ids.shape[1])[None]
    late = int(round(float(np.quantile(since[m], 0.9)) / 50.0) * 50) or 200
    used = np.bincount(batch.ids[m], minlength=32)
    ids = list(dict.fromkeys([int(g) for g in np.argsort(-used)[:3] if used[g]]
                             + list(DESIGN_IDS)))
    out = []
    for n0, when in ((0, "right after power-on"), (late, f"after {late} cycles since power-on")):
        for g in ids:
            for turn in (0.0, 90.0, 180.0, 270.0):
                s = start.copy()
                s[2] = (s[2] + turn) % 360.0
                out.append(Design(f"walk gait cycle {g} ({_id_words(g)}) for {n} cycles from "
                                  f"({s[0]:.0f}, {s[1]:.0f}) cm, heading {s[2]:.0f} deg, {when}",
                                  np.full(n, g), n0, s))
        strengths = sorted({int(strength(g)) for g in ids if strength(g) < 15})
        for st in strengths:
            for every in (1, 4):
                seq = np.array([st if (i // every) % 2 == 0 else st + 16 for i in range(n)])
                out.append(Design(f"alternate right and left turns of strength {st} (gait "
                                  f"cycles {st} and {st + 16}), switching every {every} "
                                  f"cycle{'s' if every > 1 else ''}, for {n} cycles, {when}",
                                  seq, n0, start.copy()))
    return out


def _id_words(g: int) -> str:
    s = int(strength(g))
    if s == 15:
        return "straight"
    return f"{'right' if side(g) == 0 else 'left'} turn of strength {s}"


def design_batch(ds: Sequence[Design]) -> Batch:
    n = max(len(d.ids) for d in ds)
    ids = np.stack([np.pad(d.ids, (0, n - len(d.ids)), mode="edge") for d in ds])
    mask = np.zeros(ids.shape, dtype=bool)
    for k, d in enumerate(ds):
        mask[k, : len(d.ids)] = True
    poses = np.repeat(np.stack([d.start for d in ds])[:, None], n + 1, axis=1)
    return Batch(tuple(f"design{k}" for k in range(len(ds))), ids, mask, poses,
                 np.array([d.n0 for d in ds], dtype=np.int64),
                 np.array([len(d.ids) for d in ds], dtype=np.int64))


def family_predictor(prop: Proposal, prob: Problem) -> Callable[[Batch], tuple]:
    """A family's term (with its library effects) predicting new runs, recorded after every
    run given (so a change between runs has happened); pose-dependent terms along the
    replay."""
    fam = next(f for f in FAMILIES if f.name == prop.family)

    def predict(b: Batch):
        chron = np.ones(len(b.run_ids))
        poses = b.poses
        for _ in range(2):  # the model's own path first, then the path with the term
            p = Problem(prob.rows, prob.base_effects, _with_poses(b, poses), prob.whitener)
            poses = _replay(p, prop.base, fam, prop.hyper, prop.chosen, prop.coef, chron)
        return moves_between(poses) * b.mask[..., None], np.zeros(b.ids.shape + (3,))
    return predict


def mixture_predictor(mix: dict, prob: Problem) -> Callable[[Batch], tuple]:
    """The intermittent mixture: the expected move and the extra variance of its two
    scales."""
    p, m1, m2 = mix["share"], mix["scale_major"], mix["scale_minor"]

    def predict(b: Batch):
        body, world = step_moves(prob.rows, b.ids, prob.base_effects, b.n0)
        poses = integrate(b.poses[:, 0], body * mix["expected_scale"] * b.mask[..., None],
                          None if world is None else world * b.mask[..., None])
        mv = moves_between(poses) * b.mask[..., None]
        return mv, p * (1 - p) * (m1 - m2) ** 2 * body**2 * b.mask[..., None]
    return predict


def _with_poses(b: Batch, poses: np.ndarray) -> Batch:
    return Batch(b.run_ids, b.ids, b.mask, poses, b.n0, b.lengths)


def separating_run(cands: Sequence[Candidate], batch: Batch, noise: NoiseFloor) -> dict | None:
    """The possible test run on which the candidates' predictions differ most against the
    noise (the smallest pairwise divergence, maximised), with what each predicts."""
    if len(cands) < 2:
        return None
    ds = designs(batch)
    b = design_batch(ds)
    var0 = _sigma(noise) ** 2
    preds = [c.predict(b) for c in cands]
    worst = np.full(len(ds), np.inf)
    for i in range(len(cands)):
        for k in range(i + 1, len(cands)):
            (ma, ea), (mb, eb) = preds[i], preds[k]
            va, vb = var0 + ea, var0 + eb
            j = 0.5 * (va / vb + vb / va - 2) + 0.5 * (ma - mb) ** 2 * (1 / va + 1 / vb)
            worst = np.minimum(worst, (j * b.mask[..., None]).sum(axis=(1, 2)))
    best = int(np.argmax(worst))
    n = int(b.lengths[best])
    out = {"run": ds[best].words, "gait_cycles": ds[best].ids.tolist(),
           "cycles_since_power_on_at_start": ds[best].n0,
           "start_pose": [round(float(v), 1) for v in ds[best].start],
           "separation_sigma": round(math.sqrt(max(float(worst[best]), 0.0)), 1),
           "predictions": []}
    for c, (mv, ev) in zip(cands, preds, strict=True):
        total = mv[best, :n].sum(axis=0)
        out["predictions"].append({
            "kind": c.kind, "mean_move": [round(float(v), 2) for v in mv[best, :n].mean(axis=0)],
            "total_heading_change_deg": round(float(total[2]), 1),
            "spread_per_cycle": [round(float(v), 2) for v in np.sqrt(ev[best, :n].mean(axis=0))]})
    return out


# --- where the gap lies, with the numbers ---------------------------------------------------

def _groups(batch: Batch) -> dict[str, dict[str, np.ndarray]]:
    """The residual report's contexts plus turn reversals, strength bands and position."""
    m = batch.mask
    g = contexts(batch)
    rev = reversal(batch.ids) & m
    g["turn_reversal"] = {"after_reversal": rev, "other": ~rev & m}
    i = np.broadcast_to(np.arange(batch.ids.shape[1])[None], batch.ids.shape)
    g["in_run"] = {"cycles 0-4": (i < 5) & m, "cycles 5-14": (i >= 5) & (i < 15) & m,
                   "cycles 15+": (i >= 15) & m}
    s = strength(batch.ids)
    g["turn_strength"] = {"0-4": (s <= 4) & m, "5-9": (s >= 5) & (s <= 9) & m,
                          "10-14": (s >= 10) & (s <= 14) & m}
    for axis in (0, 1):
        v = batch.poses[:, :-1, axis]
        q = np.quantile(v[m], [0.25, 0.5, 0.75]) if m.any() else np.zeros(3)
        edges = [-np.inf, *q, np.inf]
        g["xy"[axis]] = {(f"< {q[0]:.0f} cm" if k == 0 else f">= {q[2]:.0f} cm" if k == 3
                          else f"{edges[k]:.0f}-{edges[k + 1]:.0f} cm"):
                         (v >= edges[k]) & (v < edges[k + 1]) & m for k in range(4)}
    return g


def _drift_item(name: str, value: str, a: np.ndarray, b: np.ndarray) -> tuple | None:
    """A context's mean world-frame displacement against the rest's: (z, entry)."""
    n1, mu1, _, v1 = _stats2(a)
    n2, mu2, _, v2 = _stats2(b)
    z = float(np.hypot(*((mu1 - mu2) / np.sqrt(np.maximum(v1 / n1 + v2 / n2, 1e-12)))))
    d = mu1 - mu2
    size, toward = float(np.hypot(*d)), math.degrees(math.atan2(d[0], d[1])) % 360.0
    return (z, {"context": f"{name}={value}", "component": "world_drift", "z": round(z, 1),
                "mean": [round(float(v), 3) for v in mu1], "n": n1,
                "rest_mean": [round(float(v), 3) for v in mu2], "rest_n": n2,
                "text": f"{name}={value}: a world-frame drift of {size:.2f} cm per gait cycle "
                        f"toward heading {toward:.0f} deg more than elsewhere (n={n1}, "
                        f"elsewhere n={n2}) [{z:.0f} se]"})


def _stats2(x: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    n = len(x)
    return n, x.mean(axis=0), (x**2).mean(axis=0), x.var(axis=0, ddof=1)


def _stats(x: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    n = len(x)
    if n == 0:
        return 0, np.zeros(3), np.zeros(3), np.zeros(3)
    return n, x.mean(axis=0), (x**2).mean(axis=0), x.var(axis=0, ddof=1) if n > 1 else np.zeros(3)


def where_summary(batch: Batch, res: np.ndarray, noise: NoiseFloor, k: int = 4) -> dict:
    """Where the residual ``res`` (R, N, 3) lies: per component its mean square against the
    noise of one observed move, and the ``k`` contexts where it differs most from the rest
    (a mean shifted, in standard errors; a mean shifted along the move, the residual signed by
    the predicted move's, so a turn weaker both ways shows; a spread larger, as a z of the log
    ratio of mean squares; in bands of x and y, a world-frame drift), with their numbers."""
    m = batch.mask
    flat = res[m]
    var0 = _sigma(noise) ** 2
    ratio = (flat**2).mean(axis=0) / var0 if len(flat) else np.zeros(3)
    comps = [COMPONENTS[j] for j in np.argsort(-ratio)]
    # the F and T residual as a world-frame displacement (east, north): a drift tied to the
    # floor keeps its direction there while its body-frame sign turns with the heading
    h = np.radians(batch.poses[:, :-1, 2])
    world = np.stack([res[..., 0] * np.sin(h) + res[..., 1] * np.cos(h),
                      res[..., 0] * np.cos(h) - res[..., 1] * np.sin(h)], axis=-1)
    along = res * np.sign(batch.observed - res)
    items = []
    for name, groups in _groups(batch).items():
        for value, sel in groups.items():
            rest = m & ~sel
            n1, mu1, ms1, v1 = _stats(res[sel])
            n2, mu2, ms2, v2 = _stats(res[rest])
            if n1 < MIN_CONTEXT_STEPS or n2 < MIN_CONTEXT_STEPS:
                continue
            z_mean = (mu1 - mu2) / np.sqrt(np.maximum(v1 / n1 + v2 / n2, 1e-12))
            z_ms = np.log(np.maximum(ms1, 1e-12) / np.maximum(ms2, 1e-12)) / math.sqrt(
                2.0 / n1 + 2.0 / n2)
            score = np.maximum(np.abs(z_mean), z_ms)
            j = int(np.argmax(score))
            _, a1, _, w1 = _stats(along[sel])
            _, a2, _, w2 = _stats(along[rest])
            z_along = np.abs(a1 - a2) / np.sqrt(np.maximum(w1 / n1 + w2 / n2, 1e-12))
            ja = int(np.argmax(z_along))
            if z_along[ja] > score[j] + 1.0:  # clearly more than the plain mean shows
                unit = "deg" if ja == 2 else "cm"
                items.append((float(z_along[ja]), {
                    "context": f"{name}={value}", "component": COMPONENTS[ja],
                    "z": round(float(z_along[ja]), 1), "along_the_move": True,
                    "mean": round(float(a1[ja]), 3), "n": n1,
                    "rest_mean": round(float(a2[ja]), 3), "rest_n": n2,
                    "text": f"{name}={value}: {COMPONENTS[ja]} {a1[ja]:+.2f} {unit} along the "
                            f"move (n={n1}) against {a2[ja]:+.2f} elsewhere (n={n2}) "
                            f"[{z_along[ja]:.0f} se]; negative: it moves less than predicted"}))
                continue
            # a drift tied to the floor, where the floor is (elsewhere a body-frame offset
            # seen through the heading would pass for one)
            drift = (_drift_item(name, value, world[sel], world[rest]) if name in ("x", "y")
                     else None)
            if drift is not None and drift[0] > score[j]:
                items.append(drift)
                continue
            unit = "deg" if j == 2 else "cm"
            items.append((float(score[j]), {
                "context": f"{name}={value}", "component": COMPONENTS[j],
                "z": round(float(score[j]), 1),
                "mean": round(float(mu1[j]), 3), "rms": round(float(math.sqrt(ms1[j])), 3),
                "n": n1, "rest_mean": round(float(mu2[j]), 3),
                "rest_rms": round(float(math.sqrt(ms2[j])), 3), "rest_n": n2,
                "text": f"{name}={value}: {COMPONENTS[j]} mean {mu1[j]:+.2f} {unit}, rms "
                        f"{math.sqrt(ms1[j]):.2f} (n={n1}) against {mu2[j]:+.2f}, rms "
                        f"{math.sqrt(ms2[j]):.2f} elsewhere (n={n2}) [{score[j]:.0f} se]"}))
    items.sort(key=lambda t: -t[0])
    top, per = [], {}
    for z, d in items:  # at most two values of one context, and not the other side of one
        name = d["context"].split("=")[0]
        if any(t["context"].split("=")[0] == name and t["rest_n"] == d["n"] for t in top):
            continue
        if z >= MIN_CONTEXT_Z and per.get(name, 0) < 2:
            top.append(d)
            per[name] = per.get(name, 0) + 1
    # the comparison a reader asks first: first cycles after a gait change against repeats
    change = next((d for _, d in items if d["context"] == "change=after_change"), None)
    return {"component": comps[0],
            "rms_over_noise": {c: round(float(math.sqrt(ratio[j])), 2)
                               for j, c in enumerate(COMPONENTS)},
            "contexts": top[:k], "change_vs_repeat": change}
