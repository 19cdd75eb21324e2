"""`pac-host measure`: rebuild the gait table from the robot itself.

Each gait cycle id is walked ``repeats`` times from a known pose (STEP id x ``cycles``); the
observed poses become body-frame moves through :func:`pac_host.model.kinematics.moves_between`
(the inverse of the one pose update), and each id's (F, T, dH) is the mean of its moves, with
the sample standard deviation and the standard error of the mean. The standard error uses the
larger of the id's own spread and the spread pooled over all ids measured: the tracker's noise
reaches every id alike, and a handful of repeats often shows an id less spread than it is
(with 10 repeats, one id in 32 typically looks 30 % too steady), which would make its standard
error too small.

Which start pose a move is measured from: the observed one when the placer reports it (the
emulator); otherwise, with a tracker and ``cycles >= 2``, the first move (from a hand-placed
start) is dropped and the later ones, between observed poses, are used; otherwise the nominal
start pose, so a hand-placed start's error counts as noise (mark the pose on the floor).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.errors import InputError, PacError
from pac_host.model.kinematics import moves_between
from pac_host.model.table import COMPONENTS, N_IDS, GaitTable
from pac_host.robot.connect import Connection
from pac_host.robot.linked import AppendLog, observed_runs, run_seed
from pac_host.robot.recovery import Recovery, with_redos

MEASURE_START = (90.0, 90.0, 0.0)  # the middle of the area's first two rows, facing +y
SEED_KEY = 1_000_000  # keeps measure's run seeds apart from evolve's (generation, test) keys


@dataclass(frozen=True)
class MeasureConfig:
    ids: tuple[int, ...] = tuple(range(N_IDS))
    repeats: int = 5
    cycles: int = 1
    start: tuple[float, float, float] = MEASURE_START
    seed: int = 0

    def check(self) -> None:
        if not self.ids:
            raise InputError("--ids: no gait cycle ids to measure")
        bad = [i for i in self.ids if not 0 <= i < N_IDS]
        if bad:
            raise InputError(f"--ids: gait cycle ids must be 0..31, got {bad[0]}")
        if self.repeats < 2:
            raise InputError(f"--repeats must be >= 2 (a spread needs two), got {self.repeats}")
        if not 1 <= self.cycles <= 63:
            raise InputError(f"--cycles must be 1..63, got {self.cycles}")


@dataclass(frozen=True)
class Fit:
    """One id's fitted row: mean, sample standard deviation and standard error per component
    (the standard error after the pooled floor of :func:`with_pooled_floor`)."""

    gait: int
    n: int
    mean: np.ndarray
    sd: np.ndarray
    se: np.ndarray

    def to_json(self) -> dict:
        out: dict = {"id": self.gait, "n": self.n}
        for j, c in enumerate(COMPONENTS):
            out[c] = round(float(self.mean[j]), 4)
            out[f"sd_{c}"] = round(float(self.sd[j]), 4)
            out[f"se_{c}"] = round(float(self.se[j]), 4)
        return out


def parse_ids(text: str) -> tuple[int, ...]:
    """``0-31``, ``12``, ``0-3,12,16-19``: gait cycle ids in the order given, no repeats."""
    out: list[int] = []
    for part in text.split(","):
        lo, sep, hi = part.strip().partition("-")
        try:
            a, b = int(lo), int(hi) if sep else int(lo)
        except ValueError:
            raise InputError(f"--ids: expected ranges like 0-31 or 0-3,12, got {text!r}") from None
        if not (0 <= a <= b < N_IDS):
            raise InputError(f"--ids: {part.strip()!r} is not a range within 0..31")
        out += [i for i in range(a, b + 1) if i not in out]
    return tuple(out)


def fit(moves: np.ndarray, gait: int) -> Fit:
    moves = np.asarray(moves, dtype=np.float64).reshape(-1, 3)
    n = len(moves)
    sd = moves.std(axis=0, ddof=1) if n > 1 else np.full(3, np.nan)
    return Fit(gait, n, moves.mean(axis=0), sd, sd / np.sqrt(n))


def with_pooled_floor(fits: Sequence[Fit]) -> list[Fit]:
    """Standard errors from max(own spread, spread pooled over the ids) per component."""
    if len(fits) < 2:
        return list(fits)
    dof = np.array([f.n - 1 for f in fits], dtype=np.float64)
    pooled = np.sqrt((dof[:, None] * np.array([f.sd for f in fits]) ** 2).sum(0) / dof.sum())
    return [Fit(f.gait, f.n, f.mean, f.sd, np.maximum(f.sd, pooled) / np.sqrt(f.n))
            for f in fits]


def measure(
    conn: Connection,
    cfg: MeasureConfig,
    log: AppendLog,
    runs: AppendLog | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    recovery: Recovery | None = None,
) -> list[Fit]:
    """Walk and observe every id; returns one :class:`Fit` per id, in ``cfg.ids`` order.
    A measurement whose link broke down mid-way is redone from its placement
    (:func:`pac_host.robot.recovery.with_redos`); every retry, resync and redo is logged and
    counted in ``recovery``."""
    cfg.check()
    recovery = recovery if recovery is not None else Recovery()
    current = {"run_id": ""}

    def note(doc: dict) -> None:
        doc = {**doc, **current}
        recovery.note(doc)
        log(doc)

    conn.robot.link.on_event = note
    fits = []
    for gait in cfg.ids:
        moves = []
        for r in range(cfg.repeats):
            current["run_id"] = f"m{gait}-r{r}"
            moves.append(with_redos(
                conn.robot, lambda _k, g=gait, r=r: measure_once(conn, cfg, g, r, log, runs),
                note, observer=conn.observer))
        fits.append(fit(np.concatenate(moves), gait))
        if progress is not None:
            progress(gait, len(fits), len(cfg.ids))
    return with_pooled_floor(fits)


def measure_once(conn: Connection, cfg: MeasureConfig, gait: int, rep: int, log: AppendLog,
                 runs: AppendLog | None) -> np.ndarray:
    """One placement and STEP; the observed moves (k, 3) it yields."""
    run_id = f"m{gait}-r{rep}"
    seen = conn.placer.place(run_id, cfg.start, run_seed(cfg.seed, SEED_KEY + gait, rep))
    log({"type": "start", "run_id": run_id, "gait": gait, "nominal_start": list(cfg.start),
         "observed_start": seen})
    n0 = conn.robot.power_on()
    conn.observer.begin(run_id, n0, log)
    report = conn.robot.step(gait, cfg.cycles, lambda c: conn.observer.on_cycle(c.power_on), n0)
    obs = conn.observer.finish(report.done)
    if not report.completed:
        raise PacError(f"run {run_id}: the robot stopped after {report.done} of {cfg.cycles} "
                       "gait cycles")
    if obs.start is not None:  # seen by the instrument that sees every later pose
        seen = obs.start
    start = np.asarray(seen if seen is not None else cfg.start, dtype=np.float64)
    if obs.poses is not None:
        if runs is not None:
            for doc in observed_runs(run_id, start, [gait] * cfg.cycles, obs.poses, n0):
                runs(doc)
        path = np.vstack([start[None], obs.poses])
        if seen is None and cfg.cycles >= 2:
            path = path[1:]  # the hand-placed start is not observed: skip its move
        moves = moves_between(path)
        return moves[np.isfinite(moves).all(axis=1)]  # a move next to a gap was not seen
    if obs.final_pose is None:
        raise InputError(f"observer {conn.observer.name} gives neither poses nor a final pose; "
                         "measure needs one of them")
    if cfg.cycles != 1:
        raise InputError("with a final pose only, measure needs --cycles 1")
    return moves_between(np.vstack([start[None], np.asarray(obs.final_pose)[None]]))


def measured_table(current: GaitTable, fits: Sequence[Fit], name: str) -> GaitTable:
    """``current`` with the measured ids replaced by their means (effects kept)."""
    rows = np.array(current.rows)
    for f in fits:
        rows[f.gait] = f.mean
    return GaitTable(rows, current.effects, name)


def differences(current: GaitTable, fits: Sequence[Fit]) -> list[dict]:
    """Per id: measured - current per component, in cm/deg and in standard errors."""
    out = []
    for f in fits:
        d = f.mean - current.rows[f.gait]
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(f.se > 0, d / f.se, np.inf * np.sign(d))
        out.append({"id": f.gait, **{c: round(float(d[j]), 4) for j, c in enumerate(COMPONENTS)},
                    **{f"z_{c}": round(float(z[j]), 2) for j, c in enumerate(COMPONENTS)}})
    return out
