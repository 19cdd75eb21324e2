"""The noise floor: how much of the residual is tracker noise that no effect can remove.

The tracker adds independent Gaussian noise to x, y (sigma_p, cm) and h (sigma_h, deg) of every
observed pose (DESIGN.md section 3). A gait cycle's observed move is a difference of two observed
poses, so its noise is shared with the next step's: consecutive step residuals are correlated.

Method: repeated identical steps. Where a run executes the same gait cycle three times in a row
(g_{i-1} = g_i = g_{i+1}), the true moves of steps i and i+1 are the same under every effect of
the library that acts per gait cycle (table effects) or at gait changes (``transition``), so the
difference of their observed moves is noise alone (plus a tiny part of a slow drift such as
``battery_sag``). For the heading, dH_{i+1} - dH_i = e_{i+2} - 2 e_{i+1} + e_i has variance
6 sigma_h^2. For the body-frame position (F, T), linearizing the frame rotation, the squared
difference has expectation ``sigma_p^2 (8 + 4 cos dH) + 2 sigma_h^2 (F^2 + T^2)`` (sigma_h in
radians). Both are solved by moments over all such triples. This needs no model at all, so an
unmodelled effect cannot hide in the floor; a slow world-frame drift seen from a turning frame
can only raise it, making the estimate an upper bound.

With fewer than :data:`MIN_TRIPLES` such triples the estimate is flagged unreliable; with none
at all it falls back on the rms of the model's one-step residuals (an upper bound).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pac_host.diagnose.residuals import Batch

MIN_TRIPLES = 20
FLOOR = 1e-3  # smallest sigma used, so noise-free synthetic data still whitens


@dataclass(frozen=True)
class NoiseFloor:
    pos_cm: float
    heading_deg: float
    method: str
    n_used: int
    reliable: bool

    def to_json(self) -> dict:
        return {"pos_cm": round(self.pos_cm, 4), "heading_deg": round(self.heading_deg, 4),
                "method": self.method, "n_used": self.n_used, "reliable": self.reliable}


def repeated_triples(batch: Batch) -> np.ndarray:
    """Mask (R, N - 1) of steps i where g_{i-1} = g_i = g_{i+1}, all three inside the run."""
    ids, m = batch.ids, batch.mask
    sel = np.zeros((ids.shape[0], max(ids.shape[1] - 1, 0)), dtype=bool)
    if ids.shape[1] >= 3:
        sel[:, 1:] = (ids[:, :-2] == ids[:, 1:-1]) & (ids[:, 1:-1] == ids[:, 2:]) & m[:, 2:]
    return sel


def estimate_noise(batch: Batch, residuals: np.ndarray | None = None) -> NoiseFloor:
    """Estimate (sigma_p, sigma_h) from repeated identical steps of the runs in ``batch``.

    ``residuals`` (R, N, 3), the model's one-step residuals, are only used by the fallback.
    """
    obs = batch.observed
    sel = repeated_triples(batch)
    n = int(sel.sum())
    if n >= 3:
        d = obs[:, 1:] - obs[:, :-1]
        d = d[sel]
        base = obs[:, :-1][sel]
        var_h = float((d[:, 2] ** 2).mean() / 6.0)
        var_h_rad = var_h * (np.pi / 180.0) ** 2
        coupling = 2.0 * var_h_rad * (base[:, 0] ** 2 + base[:, 1] ** 2)
        weights = 8.0 + 4.0 * np.cos(np.radians(base[:, 2]))
        var_p = float(((d[:, 0] ** 2 + d[:, 1] ** 2) - coupling).sum() / weights.sum())
        return NoiseFloor(max(np.sqrt(max(var_p, 0.0)), FLOOR), max(np.sqrt(var_h), FLOOR),
                          "repeated_identical_steps", n, n >= MIN_TRIPLES)
    if residuals is None:
        raise ValueError("no repeated steps: residuals are needed for the fallback estimate")
    flat = residuals[batch.mask]
    pos = float(np.sqrt((flat[:, :2] ** 2).mean() / 2.0))  # each component: 2 sigma_p^2
    head = float(np.sqrt((flat[:, 2] ** 2).mean() / 2.0))
    return NoiseFloor(max(pos, FLOOR), max(head, FLOOR), "residual_rms_upper_bound",
                      int(batch.mask.sum()), False)
