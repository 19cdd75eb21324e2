"""Observed runs made in a simulated world: for checking the diagnosis on known answers.

The world moves the robot with the table and effects code of :mod:`pac_host.model` (the same
code the emulator and the coverage simulator use) and a tracker adds independent Gaussian noise
to every observed pose, start pose included. Turn cycles are of the kind the robot runs: a
short CGA run on the measured table and the paper's PAL test perturbations of its results.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from pac_host.coverage import START_POSE, expand
from pac_host.diagnose.runs import Run
from pac_host.model.effects import Effect, step_moves
from pac_host.model.kinematics import integrate, to_body_frame
from pac_host.model.table import measured_table
from pac_host.search import cga


def cga_turn_cycles(rng: np.random.Generator, n: int, generations: int = 15) -> np.ndarray:
    """``n`` turn cycles (n, 9, 2) like those a PAL session tests on the robot.

    A CGA population evolved briefly on the measured table, and for each of its members the
    paper's two perturbations (+-1 on each repetition count; genes set to 50 repetitions with
    probability 0.25), mixed and shuffled. Turn cycles that stand still are dropped.
    """
    pop = cga.random_population(rng, max(32, n))
    pop, _ = cga.evolve(measured_table().rows, pop, generations, rng,
                        cga.CGAConfig(population=len(pop)))
    a = pop.copy()
    nz = a[..., 1] > 0
    a[nz, 1] = np.clip(a[nz, 1] + rng.choice([-1, 1], size=int(nz.sum())), 0, 63)
    b = pop.copy()
    b[rng.random(b.shape[:2]) < 0.25, 1] = 50
    allc = np.concatenate([pop, a, b])
    allc = allc[allc[..., 1].sum(axis=1) > 0]
    return allc[rng.permutation(len(allc))[:n]]


def world_runs(
    rows: np.ndarray,
    effects: Sequence[Effect],
    turn_cycles: np.ndarray,
    n_cycles: int,
    rng: np.random.Generator,
    pos_noise_cm: float = 0.5,
    heading_noise_deg: float = 1.0,
    runs_per_session: int = 10,
    start_pose: Sequence[float] = START_POSE,
    step_noise_cm: float = 0.0,
    step_noise_deg: float = 0.0,
    perturb: Callable[..., np.ndarray] | None = None,
    lengths: Sequence[int] | None = None,
    start_exact: bool = False,
) -> list[Run]:
    """Run each turn cycle for ``n_cycles`` gait cycles in the world and observe it.

    Runs follow each other in sessions of ``runs_per_session`` after a power-on, so
    ``cycles_since_power_on`` grows within a session (what a battery effect acts on).
    ``step_noise_*`` add the robot's own step-to-step variability (Gaussian on F, T and dH of
    every gait cycle), on top of the tracker noise on every observed pose.
    ``perturb(i, body, pose, n0, ids, rng)``, if given, changes step i's body-frame moves
    (m, 3) of the m runs knowing the true poses (m, 3) before it: a world that depends on where
    the robot is (what no effect of the model may know), for testing the diagnosis on gaps
    outside its library; the runs are then integrated one gait cycle at a time.
    ``lengths`` (one per run, each at most ``n_cycles``): runs of different lengths, run k
    cut to ``lengths[k]`` gait cycles, the time since power-on counting the session's
    earlier runs' lengths. ``start_exact``: the start pose is given (the robot placed on it),
    not observed by the tracker.
    """
    ids, _ = expand(np.asarray(turn_cycles), n_cycles)
    m = len(ids)
    n0 = (np.arange(m) % runs_per_session) * n_cycles
    if lengths is not None:
        lens = np.asarray(lengths, dtype=np.int64)
        if lens.shape != (m,) or lens.min() < 1 or lens.max() > n_cycles:
            raise ValueError(f"lengths: {m} run lengths from 1 to {n_cycles} expected")
        before = np.concatenate([[0], np.cumsum(lens)[:-1]])
        session = np.arange(m) // runs_per_session
        n0 = before - before[session * runs_per_session]
    body, world = step_moves(rows, ids, effects, n0, rng=rng)
    if step_noise_cm or step_noise_deg:
        body = body + rng.normal(size=body.shape) * np.array(
            [step_noise_cm, step_noise_cm, step_noise_deg])
    start = np.broadcast_to(np.asarray(start_pose, dtype=np.float64), (m, 3))
    if perturb is None:
        poses = integrate(start, body, world)
    else:
        poses = np.empty((m, body.shape[1] + 1, 3))
        poses[:, 0] = start
        for i in range(body.shape[1]):
            b = perturb(i, body[:, i], poses[:, i], n0, ids, rng)
            w = None if world is None else world[:, i : i + 1]
            poses[:, i + 1] = integrate(poses[:, i], b[:, None], w)[:, -1]
    sd = np.array([pos_noise_cm, pos_noise_cm, heading_noise_deg])
    obs = poses + rng.normal(size=poses.shape) * sd
    if start_exact:
        obs[:, 0] = start
    cut = [n_cycles] * m if lengths is None else [int(v) for v in lengths]
    return [Run(f"run{k:03d}", obs[k, 0], ids[k, : cut[k]], obs[k, 1 : cut[k] + 1], int(n0[k]))
            for k in range(m)]


# Moderate magnitudes of each effect for blind cases: (sampler, stated range).
MODERATE = {
    "turn_shift": (lambda r: {"k": int(r.choice([-2, -1, 1, 2]))}, "k in {-2, -1, 1, 2}"),
    "turn_scale": (lambda r: {"c": 1 + r.choice([-1, 1]) * r.uniform(0.08, 0.2)},
                   "c in 1 +- [0.08, 0.2]"),
    "stride_scale": (lambda r: {"a": 1 + r.choice([-1, 1]) * r.uniform(0.05, 0.12)},
                     "a in 1 +- [0.05, 0.12]"),
    "yaw_bias": (lambda r: {"delta": r.choice([-1, 1]) * r.uniform(0.3, 1.0)},
                 "delta in +-[0.3, 1.0] deg/cycle"),
    "lateral_slip": (lambda r: {"gamma": r.choice([-1, 1]) * r.uniform(0.03, 0.08)},
                     "gamma in +-[0.03, 0.08] cm/deg"),
    "transition": (lambda r: {"alpha": r.uniform(0.2, 0.6)}, "alpha in [0.2, 0.6]"),
    "battery_sag": (lambda r: {"beta": r.uniform(1e-4, 4e-4)}, "beta in [1e-4, 4e-4] /cycle"),
    "floor_slope": (lambda r: {"s": r.uniform(0.2, 0.6), "theta": r.uniform(0, 360)},
                    "s in [0.2, 0.6] cm/cycle, theta in [0, 360)"),
}


def moderate_effect(name: str, rng: np.random.Generator) -> Effect:
    """An effect with parameters drawn from its :data:`MODERATE` range."""
    return Effect(name, MODERATE[name][0](rng))


def perturbed_rows(rows: np.ndarray, rng: np.random.Generator, pos_cm: float = 0.3,
                   heading_deg: float = 0.5) -> np.ndarray:
    """A table near ``rows``: every entry moved by Gaussian noise (a re-measured robot)."""
    return rows + rng.normal(size=rows.shape) * np.array([pos_cm, pos_cm, heading_deg])


def blind_case(
    rng: np.random.Generator,
    effects: Sequence[Effect],
    n_runs: int = 40,
    n_cycles: int = 60,
    pos_noise_cm: float = 0.5,
    heading_noise_deg: float = 1.0,
    perturb_table: bool = False,
    holdout_fraction: float = 0.3,
    step_noise: tuple[float, float] = (0.0, 0.0),
    perturb: Callable[..., np.ndarray] | None = None,
    lengths: Sequence[int] | None = None,
    start_exact: bool = False,
    runs_per_session: int = 10,
) -> tuple[np.ndarray, list[Run], list[Run]]:
    """A true table, runs in a world with ``effects``, split into fitting and held-out runs.

    The table the diagnosis is given is the true table without the effects; returns
    (rows, fitting runs, held-out runs). ``lengths``: one run per entry, of that many gait
    cycles (instead of ``n_runs`` of ``n_cycles``); ``start_exact`` and ``runs_per_session``
    as in :func:`world_runs`.
    """
    from pac_host.diagnose.pipeline import split_runs

    rows = measured_table().rows
    if perturb_table:
        rows = perturbed_rows(rows, rng)
    if lengths is not None:
        n_runs, n_cycles = len(lengths), int(max(lengths))
    cycles = cga_turn_cycles(rng, n_runs)
    runs = world_runs(rows, effects, cycles, n_cycles, rng, pos_noise_cm, heading_noise_deg,
                      runs_per_session, step_noise_cm=step_noise[0],
                      step_noise_deg=step_noise[1], perturb=perturb, lengths=lengths,
                      start_exact=start_exact)
    fit, hold = split_runs(runs, holdout_fraction, rng)
    return rows, fit, hold


# Gaps outside the library, for blind checks of what the diagnosis says when no effect of its
# library is the cause. Each maker takes a Generator and a magnitude level (0 weak .. 2 strong)
# and returns (perturb for :func:`world_runs`, a description of the truth). The kind is what
# the diagnosis should name.
def _uniform(rng: np.random.Generator, ranges: Sequence[tuple[float, float]], level: int) -> float:
    lo, hi = ranges[level]
    return float(rng.uniform(lo, hi))


def _stall(rng, level):
    p = _uniform(rng, [(0.04, 0.08), (0.08, 0.15), (0.15, 0.3)], level)

    def perturb(i, body, pose, n0, ids, r):
        stalled = r.random(len(body)) < p
        return body * np.where(stalled, r.uniform(0.0, 0.25, len(body)), 1.0)[:, None]
    return perturb, {"p": p}


def _wobble(rng, level):
    amp = _uniform(rng, [(1.0, 2.0), (2.0, 3.5), (3.5, 6.0)], level)
    period, phase = float(rng.uniform(4.0, 15.0)), float(rng.uniform(0, 2 * np.pi))

    def perturb(i, body, pose, n0, ids, r):
        out = body.copy()
        out[:, 2] += amp * np.sin(2 * np.pi * (n0 + i) / period + phase)
        return out
    return perturb, {"amplitude_deg": amp, "period": period}


def _payload(rng, level):
    d = _uniform(rng, [(0.06, 0.12), (0.12, 0.2), (0.2, 0.4)], level)
    start = float(rng.uniform(0.3, 0.7))  # share of the runs (in recorded order) before it

    def perturb(i, body, pose, n0, ids, r):
        after = np.arange(len(body)) >= start * len(body)
        return body * np.where(after, 1.0 - d, 1.0)[:, None]
    return perturb, {"shrink": d, "from_run_share": start}


def _floor_patch(rng, level):
    f = _uniform(rng, [(0.1, 0.2), (0.2, 0.35), (0.35, 0.6)], level)
    axis = int(rng.integers(0, 2))  # 0: a band of x, 1: a band of y
    lo = float(rng.uniform(20.0, 100.0) if axis == 0 else rng.uniform(30.0, 150.0))
    width = float(rng.uniform(50.0, 90.0))

    def perturb(i, body, pose, n0, ids, r):
        inside = (pose[:, axis] >= lo) & (pose[:, axis] < lo + width)
        return body * np.where(inside, 1.0 - f, 1.0)[:, None]
    return perturb, {"friction": f, "axis": "xy"[axis], "band": [lo, lo + width]}


def _heading_pull(rng, level):
    c = _uniform(rng, [(0.4, 0.8), (0.8, 1.5), (1.5, 3.0)], level)
    toward = float(rng.uniform(0.0, 360.0))

    def perturb(i, body, pose, n0, ids, r):
        out = body.copy()
        out[:, 2] += c * np.sin(np.radians(toward - pose[:, 2]))
        return out
    return perturb, {"deg_per_cycle": c, "toward": toward}


def _warmup(rng, level):
    a = _uniform(rng, [(0.1, 0.2), (0.2, 0.35), (0.35, 0.6)], level)
    tau = float(rng.uniform(40.0, 150.0))

    def perturb(i, body, pose, n0, ids, r):
        return body * (1.0 - a * np.exp(-(n0 + i) / tau))[:, None]
    return perturb, {"cold_loss": a, "tau_cycles": tau}


def _turn_dir(ids: np.ndarray) -> np.ndarray:
    """+1 on a right turn, -1 on a left turn, 0 on a straight gait cycle (strength 15)."""
    return np.where((ids & 15) == 15, 0, np.where(ids >> 4 == 0, 1, -1))


def _weak_leg(rng, level):
    """A weak leg: on turns to one side only, the stride is shorter (and the turn a little
    weaker)."""
    d = _uniform(rng, [(0.08, 0.14), (0.14, 0.22), (0.22, 0.35)], level)
    on = int(rng.integers(0, 2))  # 0: right turns, 1: left turns

    def perturb(i, body, pose, n0, ids, r):
        g = ids[:, i]
        hit = ((g >> 4) == on) & ((g & 15) < 15)
        return body * np.where(hit[:, None], [1.0 - d, 1.0, 1.0 - d / 2], 1.0)
    return perturb, {"stride_loss": d, "side": ("right", "left")[on]}


def _backlash(rng, level):
    """Backlash: the first gait cycle after the turn direction reverses loses a few degrees of
    its turn (and a little of its stride) while the play is taken up."""
    b = _uniform(rng, [(1.5, 2.5), (2.5, 4.0), (4.0, 6.0)], level)

    def perturb(i, body, pose, n0, ids, r):
        if i == 0:
            return body
        cur, prev = _turn_dir(ids[:, i]), _turn_dir(ids[:, i - 1])
        hit = (cur * prev) < 0
        out = body.copy()
        out[:, 2] -= np.where(hit, b * np.sign(body[:, 2]), 0.0)
        out[:, 0] -= np.where(hit, 0.1 * b, 0.0)
        return out
    return perturb, {"deg_lost": b}


def _sag_additive(rng, level):
    """A battery sag that takes a fixed length off every stride (not a share of it), growing
    with the time since power-on."""
    c = _uniform(rng, [(0.3, 0.5), (0.5, 0.9), (0.9, 1.5)], level)  # cm per 100 cycles

    def perturb(i, body, pose, n0, ids, r):
        out = body.copy()
        out[:, 0] -= c * (n0 + i) / 100.0
        return out
    return perturb, {"cm_per_100_cycles": c}


def _slope_patch(rng, level):
    """A ramp in one part of the floor: inside a band of x or y the robot drifts downhill."""
    s = _uniform(rng, [(0.3, 0.5), (0.5, 0.8), (0.8, 1.3)], level)  # cm per gait cycle
    theta = float(rng.uniform(0.0, 360.0))
    axis = int(rng.integers(0, 2))
    lo = float(rng.uniform(20.0, 100.0) if axis == 0 else rng.uniform(30.0, 150.0))
    width = float(rng.uniform(60.0, 100.0))
    dx, dy = s * np.sin(np.radians(theta)), s * np.cos(np.radians(theta))

    def perturb(i, body, pose, n0, ids, r):
        inside = (pose[:, axis] >= lo) & (pose[:, axis] < lo + width)
        f, t = to_body_frame(dx, dy, pose[:, 2])
        out = body.copy()
        out[:, 0] += np.where(inside, f, 0.0)
        out[:, 1] += np.where(inside, t, 0.0)
        return out
    return perturb, {"cm_per_cycle": s, "toward": theta, "axis": "xy"[axis],
                     "band": [lo, lo + width]}


def _tether(rng, level):
    """A cable to a point on the floor: it pulls toward that point, more the farther the robot
    is from it (a world-frame drift growing with distance)."""
    k = _uniform(rng, [(0.15, 0.3), (0.3, 0.5), (0.5, 0.8)], level)  # cm per cycle per metre
    ax, ay = float(rng.uniform(0.0, 150.0)), float(rng.uniform(0.0, 150.0))

    def perturb(i, body, pose, n0, ids, r):
        dx, dy = -k * (pose[:, 0] - ax) / 100.0, -k * (pose[:, 1] - ay) / 100.0
        f, t = to_body_frame(dx, dy, pose[:, 2])
        out = body.copy()
        out[:, 0] += f
        out[:, 1] += t
        return out
    return perturb, {"cm_per_cycle_per_m": k, "anchor": [ax, ay]}


def _pause_warmup(rng, level):
    """Motors that cool during the pause between runs: every run starts with shorter moves
    that recover over its first cycles."""
    a = _uniform(rng, [(0.15, 0.25), (0.25, 0.4), (0.4, 0.6)], level)
    tau = float(rng.uniform(3.0, 10.0))

    def perturb(i, body, pose, n0, ids, r):
        return body * (1.0 - a * math.exp(-i / tau))
    return perturb, {"cold_loss": a, "tau_cycles": tau}


def _carpet(rng, level):
    """A carpet's pile: strides are longer walking with the grain, shorter against it."""
    a = _uniform(rng, [(0.04, 0.07), (0.07, 0.12), (0.12, 0.2)], level)
    grain = float(rng.uniform(0.0, 360.0))

    def perturb(i, body, pose, n0, ids, r):
        out = body.copy()
        out[:, 0] *= 1.0 + a * np.cos(np.radians(pose[:, 2] - grain))
        return out
    return perturb, {"stride_change": a, "grain": grain}


OUTSIDE = {
    "stall": ("intermittent", _stall),
    "wobble": ("periodic", _wobble),
    "payload": ("sudden_change", _payload),
    "floor_patch": ("position", _floor_patch),
    "heading_pull": ("heading", _heading_pull),
    "warmup": ("time_since_power_on", _warmup),
    "weak_leg": ("turn", _weak_leg),
    "backlash": ("previous_gait_cycle", _backlash),
    "sag_additive": ("time_since_power_on", _sag_additive),
    "slope_patch": ("position", _slope_patch),
    "tether": ("position", _tether),
    "carpet": ("heading", _carpet),
    "pause_warmup": ("time_in_run", _pause_warmup),
}
