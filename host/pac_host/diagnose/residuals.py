"""Where the gap lies: per-gait-cycle residuals in the body frame, and the rollout view.

For step i of a run the model predicts the move (F, T, dH) of gait cycle g_i from the observed
pose before it (the table, the effects of :mod:`pac_host.model.effects`, and any world-frame
drift expressed in the frame of that observed pose); the observed move is the displacement to
the next observed pose in the same frame (:func:`pac_host.model.kinematics.moves_between`).
The residual is observed minus predicted. One-step residuals do not accumulate heading errors,
so they show where (which gait cycle, which component, which context) the model is wrong.

The rollout view replays each whole run on the model from its start pose and compares the end
pose with the observed one, and the coverage figures of both paths.

Runs of different lengths are padded into one batch (:class:`Batch`) so every computation is
one numpy operation over all runs; padded steps repeat the run's last gait cycle (so they add
no gait change) and are masked out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from pac_host.coverage import coverage_of_poses
from pac_host.diagnose.runs import Run
from pac_host.model.effects import Effect, step_moves
from pac_host.model.kinematics import integrate, moves_between, to_body_frame
from pac_host.model.table import COMPONENTS, N_IDS, side, strength


@dataclass(frozen=True)
class Batch:
    """Runs padded to a common length N: ids (R, N), mask (R, N), poses (R, N + 1, 3)."""

    run_ids: tuple[str, ...]
    ids: np.ndarray
    mask: np.ndarray
    poses: np.ndarray
    n0: np.ndarray  # (R,) gait cycles since power-on before each run
    lengths: np.ndarray  # (R,)

    @cached_property
    def observed(self) -> np.ndarray:
        """Observed body-frame moves (R, N, 3), zero on padded steps."""
        return moves_between(self.poses) * self.mask[..., None]

    @property
    def n_steps(self) -> int:
        return int(self.mask.sum())

    def subset(self, index: Sequence[int] | np.ndarray) -> Batch:
        index = np.asarray(index, dtype=np.int64)
        n = int(self.lengths[index].max()) if len(index) else 0
        return Batch(tuple(self.run_ids[i] for i in index), self.ids[index, :n],
                     self.mask[index, :n], self.poses[index, : n + 1], self.n0[index],
                     self.lengths[index])


def batch_of(runs: Sequence[Run]) -> Batch:
    """Pad runs into one :class:`Batch`."""
    r = len(runs)
    n = max(run.n for run in runs)
    ids = np.empty((r, n), dtype=np.int64)
    mask = np.zeros((r, n), dtype=bool)
    poses = np.empty((r, n + 1, 3))
    for k, run in enumerate(runs):
        m = run.n
        ids[k, :m] = run.gait_cycles
        ids[k, m:] = run.gait_cycles[-1]
        mask[k, :m] = True
        poses[k, : m + 1] = run.all_poses()
        poses[k, m + 1 :] = run.poses[-1]  # padded poses stand still
    n0 = np.array([run.cycles_since_power_on for run in runs], dtype=np.int64)
    lengths = np.array([run.n for run in runs], dtype=np.int64)
    return Batch(tuple(run.run_id for run in runs), ids, mask, poses, n0, lengths)


def predicted_moves(rows: np.ndarray, batch: Batch, effects: Sequence[Effect]) -> np.ndarray:
    """Model moves (R, N, 3) of every step, in the frame of the observed pose before it."""
    body, world = step_moves(rows, batch.ids, effects, batch.n0)
    if world is not None:
        f, t = to_body_frame(world[..., 0], world[..., 1], batch.poses[:, :-1, 2])
        body = body.copy()
        body[..., 0] += f
        body[..., 1] += t
    return body


def row_design(batch: Batch, effects: Sequence[Effect]) -> np.ndarray:
    """d(predicted step) / d(row g), the same for F, T and dH: (R, N, 32), 0 on padded steps.

    For fixed sequence effects the prediction is linear in the rows (transition blends two
    rows, battery sag scales one), so unit tables give the coefficients exactly."""
    if not effects:  # each step is its own row: one-hot
        onehot = batch.ids[..., None] == np.arange(N_IDS)
        return (onehot & batch.mask[..., None]).astype(np.float64)
    zero = predicted_moves(np.zeros((N_IDS, 3)), batch, effects)[..., 0]
    cols = []
    for g in range(N_IDS):
        unit = np.zeros((N_IDS, 3))
        unit[g] = 1.0
        cols.append(predicted_moves(unit, batch, effects)[..., 0] - zero)
    return np.stack(cols, axis=-1) * batch.mask[..., None]


def step_residuals(rows: np.ndarray, batch: Batch, effects: Sequence[Effect]) -> np.ndarray:
    """Observed minus predicted moves (R, N, 3): cm forward, cm lateral, degrees; 0 if padded."""
    return (batch.observed - predicted_moves(rows, batch, effects)) * batch.mask[..., None]


def rollout_poses(rows: np.ndarray, batch: Batch, effects: Sequence[Effect]) -> np.ndarray:
    """The model's replay (R, N + 1, 3) of every run from its observed start pose."""
    body, world = step_moves(rows, batch.ids, effects, batch.n0)
    body = body * batch.mask[..., None]
    if world is not None:
        world = world * batch.mask[..., None]
    return integrate(batch.poses[:, 0], body, world)


def end_errors(rows: np.ndarray, batch: Batch, effects: Sequence[Effect]) -> np.ndarray:
    """Per run: distance (cm) between the model's replayed end pose and the observed one."""
    sim = rollout_poses(rows, batch, effects)
    k = np.arange(len(batch.lengths))
    d = sim[k, batch.lengths, :2] - batch.poses[k, batch.lengths, :2]
    return np.hypot(d[:, 0], d[:, 1])


def coverage_gap(rows: np.ndarray, batch: Batch, effects: Sequence[Effect]) -> dict:
    """Predicted minus observed coverage figures, per run and on average."""
    sim = rollout_poses(rows, batch, effects)
    out: dict = {"per_run": []}
    keys = ("blocks_covered", "blocks_covered_once")
    diffs = {k: [] for k in keys}
    for r, n in enumerate(batch.lengths):
        obs = coverage_of_poses(batch.poses[r, : n + 1])
        pred = coverage_of_poses(sim[r, : n + 1])
        row = {"run_id": batch.run_ids[r]}
        for k in keys:
            o, p = int(getattr(obs, k)), int(getattr(pred, k))
            row[k] = {"observed": o, "predicted": p}
            diffs[k].append(p - o)
        out["per_run"].append(row)
    for k in keys:
        d = np.array(diffs[k])
        out[k] = {"mean_diff": float(d.mean()), "mean_abs_diff": float(np.abs(d).mean()),
                  "runs_differing": int((d != 0).sum())}
    return out


def _stats(res: np.ndarray) -> dict:
    """n, mean, standard error and rms of residual rows (k, 3)."""
    n = len(res)
    if n == 0:
        return {"n": 0, "mean": [0.0] * 3, "se": [0.0] * 3, "rms": [0.0] * 3}
    mean = res.mean(axis=0)
    se = res.std(axis=0, ddof=1) / np.sqrt(n) if n > 1 else np.zeros(3)
    rms = np.sqrt((res**2).mean(axis=0))
    return {"n": int(n), "mean": _r(mean), "se": _r(se), "rms": _r(rms)}


def _r(v: np.ndarray) -> list[float]:
    return [round(float(x), 4) for x in v]


def contexts(batch: Batch) -> dict[str, dict[str, np.ndarray]]:
    """Named groups of steps (boolean masks (R, N)) by context.

    ``change``: first cycle after a change of gait cycle vs a repeat (a run's first step counts
    as neither); ``power_on``: gait cycles since power-on (n0 + i) in quartile bins;
    ``heading``: observed heading before the step in four 90-degree sectors around N, E, S, W;
    ``turn``: right turn, left turn or straight (strength 15) gait cycles.
    """
    ids, m = batch.ids, batch.mask
    change = np.zeros_like(m)
    change[:, 1:] = ids[:, 1:] != ids[:, :-1]
    first = np.zeros_like(m)
    first[:, 0] = True
    since = batch.n0[:, None] + np.arange(ids.shape[1])[None]
    edges = np.unique(np.quantile(since[m], [0, 0.25, 0.5, 0.75, 1.0]).round())
    power: dict[str, np.ndarray] = {}
    for k in range(len(edges) - 1):
        lo, hi = edges[k], edges[k + 1]
        sel = (since >= lo) & ((since < hi) if k < len(edges) - 2 else (since <= hi))
        power[f"{int(lo)}-{int(hi)}"] = sel & m
    h = np.mod(batch.poses[:, :-1, 2] + 45.0, 360.0) // 90.0
    straight = strength(ids) == 15
    return {
        "change": {"after_change": change & m, "repeat": ~change & ~first & m},
        "power_on": power,
        "heading": {name: (h == k) & m for k, name in enumerate(("N", "E", "S", "W"))},
        "turn": {"right": (side(ids) == 0) & ~straight & m,
                 "left": (side(ids) == 1) & ~straight & m, "straight": straight & m},
    }


def where_report(batch: Batch, res: np.ndarray) -> dict:
    """The ``where`` section: residuals by gait cycle id, by component and by context."""
    m = batch.mask
    by_id = []
    for g in range(32):
        sel = (batch.ids == g) & m
        if sel.any():
            by_id.append({"id": g, **_stats(res[sel])})
    flat = res[m]
    by_comp = {c: round(float(np.sqrt((flat[:, j] ** 2).mean())), 4)
               for j, c in enumerate(COMPONENTS)}
    by_ctx = {name: {k: _stats(res[sel]) for k, sel in groups.items()}
              for name, groups in contexts(batch).items()}
    return {"by_gait_cycle": by_id, "by_component": by_comp, "by_context": by_ctx}


def top_places(where: dict, k: int = 3) -> list[str]:
    """The k gait cycles and contexts whose mean residual stands out most (in standard errors)."""
    items = []
    for row in where["by_gait_cycle"]:
        for j, c in enumerate(COMPONENTS):
            if row["n"] > 2 and row["se"][j] > 0:
                items.append((abs(row["mean"][j]) / row["se"][j],
                              f"gait {row['id']} {c} {row['mean'][j]:+.2f} (n={row['n']})"))
    for name, groups in where["by_context"].items():
        for g, row in groups.items():
            for j, c in enumerate(COMPONENTS):
                if row["n"] > 2 and row["se"][j] > 0:
                    items.append((abs(row["mean"][j]) / row["se"][j],
                                  f"{name}={g} {c} {row['mean'][j]:+.2f} (n={row['n']})"))
    items.sort(key=lambda t: -t[0])
    return [f"{text} [{z:.0f} se]" for z, text in items[:k] if z > 3]
