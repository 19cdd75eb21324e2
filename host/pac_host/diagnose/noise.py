"""The noise floor: how much of the residual is noise that no effect can remove.

Two kinds of noise. The tracker adds independent Gaussian noise to x, y (sigma_p, cm) and h
(sigma_h, deg) of every observed pose (DESIGN.md section 3); a gait cycle's observed move is a
difference of two observed poses, so that noise is shared by consecutive steps. A real robot
also varies from step to step by itself (process noise: q_p cm on F and T, q_h deg on dH,
independent per step), which accumulates along a run. Both are the floor: no effect of the
library removes them, and the likelihood (:mod:`.likelihood`) must know both, or a robot's own
step variability would look like unexplained structure.

Method: repeated identical steps. Where a run executes the same gait cycle four times in a row
(g_{i-1} = g_i = g_{i+1} = g_{i+2}), the true moves of steps i, i+1, i+2 are the same under
every table effect and ``transition``, so the differences d_i = o_{i+1} - o_i of their observed
moves hold noise alone (plus a tiny part of a slow drift such as ``battery_sag``). For the
heading, d_i = e_{i+2} - 2 e_{i+1} + e_i + u_{i+1} - u_i, so E[d_i^2] = 6 sigma_h^2 + 2 q_h^2 and
E[d_i d_{i+1}] = -4 sigma_h^2 - q_h^2: two moments, two unknowns. For the body-frame position,
with the frame rotating by dH between steps and the heading noise coupling in through
(T, -F) (radians), E|d_i|^2 = sigma_p^2 (8 + 4 cos dH) + 2 sigma_h^2 (F^2 + T^2) + 4 q_p^2 and
E[d_i . d_{i+1}] = -sigma_p^2 (4 + 4 cos dH) - sigma_h^2 (F^2 + T^2) - 2 q_p^2, solved the same way
(sums over all such quadruples; a process-noise variance is kept only when clearly above
zero). This needs no model, so an unmodelled effect cannot hide in
the floor.

With fewer than :data:`MIN_REPEATS` such quadruples the estimate is flagged unreliable; with
none, triples give the tracker noise alone (no process noise); with no repeats at all it falls
back on the rms of the model's one-step residuals (an upper bound).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pac_host.diagnose.residuals import Batch

MIN_REPEATS = 20
FLOOR = 1e-3  # smallest sigma used, so noise-free synthetic data still whitens


@dataclass(frozen=True)
class NoiseFloor:
    pos_cm: float  # tracker noise on x and y of each pose
    heading_deg: float  # tracker noise on h of each pose
    method: str
    n_used: int
    reliable: bool
    step_cm: float = 0.0  # the robot's own step-to-step variability of F and T
    step_deg: float = 0.0  # ... and of dH

    def to_json(self) -> dict:
        return {"pos_cm": round(self.pos_cm, 4), "heading_deg": round(self.heading_deg, 4),
                "step_cm": round(self.step_cm, 4), "step_deg": round(self.step_deg, 4),
                "method": self.method, "n_used": self.n_used, "reliable": self.reliable}


def repeated_steps(batch: Batch, k: int) -> np.ndarray:
    """Mask (R, N) of steps i where g_{i-1} = g_i = ... = g_{i+k-2}, all inside the run (the
    first step is a repeat of the one before it, so it is no gait change)."""
    ids, m = batch.ids, batch.mask
    r, n = ids.shape
    sel = np.zeros((r, n), dtype=bool)
    if n >= k:  # steps i = 1 .. n - k + 1
        ok = m[:, k - 1 :].copy()
        for j in range(k - 1):
            ok &= ids[:, j : n - k + 1 + j] == ids[:, j + 1 : n - k + 2 + j]
        sel[:, 1 : n - k + 2] = ok
    return sel


def _significant(terms: np.ndarray, z: float = 1.0) -> float:
    """The mean of per-quadruple moment terms when it is clearly above zero, else 0.

    A process-noise variance is kept only when it exceeds ``z`` standard errors (generous,
    since overlapping quadruples are not independent): an estimate that is noise alone would
    otherwise make the likelihood under-confident.
    """
    mean = float(terms.mean())
    se = float(terms.std(ddof=1) / np.sqrt(len(terms))) if len(terms) > 1 else np.inf
    return mean if mean > z * se else 0.0


def estimate_noise(batch: Batch, residuals: np.ndarray | None = None) -> NoiseFloor:
    """Estimate the noise floor from repeated identical steps of the runs in ``batch``.

    ``residuals`` (R, N, 3), the model's one-step residuals, are only used by the fallback.
    """
    obs = batch.observed
    d = np.zeros_like(obs)
    d[:, :-1] = obs[:, 1:] - obs[:, :-1]  # d_i = o_{i+1} - o_i
    base = obs
    to_rad2 = (np.pi / 180.0) ** 2
    quad = repeated_steps(batch, 4)
    n4 = int(quad.sum())
    if n4 >= 3:
        d0, d1, b = d[quad], d[:, 1:][quad[:, :-1]], base[quad]
        g0h, g1h = float((d0[:, 2] ** 2).sum()), float((d0[:, 2] * d1[:, 2]).sum())
        var_h = max(-(g0h + 2 * g1h) / (2 * n4), 0.0)
        q_h = _significant((d0[:, 2] ** 2 - 6 * var_h) / 2)
        cos = np.cos(np.radians(b[:, 2]))
        ft2 = (b[:, 0] ** 2 + b[:, 1] ** 2) * to_rad2
        s0 = float((d0[:, :2] ** 2).sum())
        s1 = float((d0[:, :2] * d1[:, :2]).sum())
        var_p = max(-(s0 + 2 * s1) / (4 * cos.sum()), 0.0)
        q_p = _significant(((d0[:, :2] ** 2).sum(axis=1) - var_p * (8 + 4 * cos)
                            - 2 * var_h * ft2) / 4)
        return NoiseFloor(max(np.sqrt(var_p), FLOOR), max(np.sqrt(var_h), FLOOR),
                          "repeated_identical_steps", n4, n4 >= MIN_REPEATS,
                          float(np.sqrt(q_p)), float(np.sqrt(q_h)))
    tri = repeated_steps(batch, 3)
    n3 = int(tri.sum())
    if n3 >= 3:
        d0, b = d[tri], base[tri]
        var_h = float((d0[:, 2] ** 2).mean() / 6.0)
        coupling = 2.0 * var_h * to_rad2 * (b[:, 0] ** 2 + b[:, 1] ** 2)
        weights = 8.0 + 4.0 * np.cos(np.radians(b[:, 2]))
        var_p = float(((d0[:, 0] ** 2 + d0[:, 1] ** 2) - coupling).sum() / weights.sum())
        return NoiseFloor(max(np.sqrt(max(var_p, 0.0)), FLOOR), max(np.sqrt(var_h), FLOOR),
                          "repeated_identical_steps_tracker_only", n3, False)
    if residuals is None:
        raise ValueError("no repeated steps: residuals are needed for the fallback estimate")
    flat = residuals[batch.mask]
    pos = float(np.sqrt((flat[:, :2] ** 2).mean() / 2.0))  # each component: 2 sigma_p^2
    head = float(np.sqrt((flat[:, 2] ** 2).mean() / 2.0))
    return NoiseFloor(max(pos, FLOOR), max(head, FLOOR), "residual_rms_upper_bound",
                      int(batch.mask.sum()), False)
