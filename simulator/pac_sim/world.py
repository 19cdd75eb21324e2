"""The simulated world: where the robot really is after each gait cycle.

The pose advances with a true gait table plus unmodelled effects and the table's step noise
through the model's own ``noisy_step_moves``/``integrate`` (the one definition of
kinematics); observers (the tracker feed)
receive the pose seen by an overhead camera, with Gaussian noise from a seeded generator.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.coverage import START_POSE  # the paper's start pose
from pac_host.model import Effect, GaitTable, integrate
from pac_host.model.step_noise import noisy_step_moves


@dataclass(frozen=True)
class PoseSample:
    """One gait cycle as the world saw it: true pose and the tracker's noisy observation."""

    seq: int  # gait cycles the world has executed since the emulator started (1, 2, ...)
    gait: int  # -1 for a snapshot that follows no gait cycle
    power_on: int  # gait cycles since the Stamp's last power-on/reset, this one included
    true_pose: tuple[float, float, float]
    observed: tuple[float, float, float]


class World:
    def __init__(
        self,
        table: GaitTable,
        effects: Sequence[Effect] = (),
        start: Sequence[float] = START_POSE,
        noise: tuple[float, float] = (0.0, 0.0),
        rng: np.random.Generator | None = None,
    ) -> None:
        self.table = table
        self.effects = tuple(table.effects) + tuple(effects)
        self.pose = np.asarray(start, dtype=np.float64).copy()
        self.noise = noise
        rng = rng if rng is not None else np.random.default_rng(0)
        # the first two streams are the tracker's; the third is a random effect's (a stall ...);
        # the fourth the table's step noise (spawned last: without noise no other draw changes)
        self._cycle_rng, self._snap_rng, self._effect_rng, self._step_rng = rng.spawn(4)
        self.seq = 0
        self.power_on = 0
        self.history: list[PoseSample] = []
        self.observers: list[Callable[[PoseSample], None]] = []
        self._lock = threading.Lock()

    def _observe(self, rng: np.random.Generator) -> tuple[float, float, float]:
        pos, head = self.noise
        n = rng.normal(size=3) * np.array([pos, pos, head])
        return tuple(float(v) for v in self.pose + n)

    def advance(self, gait: int, n0: int, prev_gait: int | None) -> PoseSample:
        """Execute one gait cycle. ``n0``: cycles since power-on before it; ``prev_gait``: the
        gait just before it in the same run (None at a run's start)."""
        body, drift = noisy_step_moves(
            self.table.rows, np.array([gait]), self.effects, self.table.step_noise,
            self._step_rng, n0=n0, prev_gait=prev_gait, effect_rng=self._effect_rng,
        )
        with self._lock:
            self.pose = integrate(self.pose, body, drift)[-1]
            self.seq += 1
            self.power_on = n0 + 1
            s = PoseSample(
                self.seq,
                gait,
                n0 + 1,
                tuple(float(v) for v in self.pose),
                self._observe(self._cycle_rng),
            )
            self.history.append(s)
        for ob in list(self.observers):
            ob(s)
        return s

    def place(
        self, pose: Sequence[float], noise_seed: int | None = None
    ) -> tuple[float, float, float]:
        """Put the robot at ``pose``, as an operator does before a run; returns the pose the
        tracker sees there. ``noise_seed`` restarts the tracker's noise streams, so the noise of
        a run depends on the run alone and not on what the emulator did before it (an
        interrupted experiment resumed in a new process sees the same noise)."""
        with self._lock:
            self.pose = np.asarray(pose, dtype=np.float64).copy()
            if noise_seed is not None:
                seq = np.random.SeedSequence(noise_seed)
                self._cycle_rng, self._snap_rng, self._effect_rng, self._step_rng = (
                    np.random.default_rng(s) for s in seq.spawn(4))
            return self._observe(self._snap_rng)

    def snapshot(self) -> PoseSample:
        """The current pose as the tracker sees it now (its noise from a separate stream)."""
        with self._lock:
            p = tuple(float(v) for v in self.pose)
            return PoseSample(self.seq, -1, self.power_on, p, self._observe(self._snap_rng))
