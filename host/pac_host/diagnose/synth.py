"""Observed runs made in a simulated world: for checking the diagnosis on known answers.

The world moves the robot with the table and effects code of :mod:`pac_host.model` (the same
code the emulator and the coverage simulator use) and a tracker adds independent Gaussian noise
to every observed pose, start pose included. Turn cycles are of the kind the robot runs: a
short CGA run on the measured table and the paper's PAL test perturbations of its results.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pac_host import cga
from pac_host.coverage import START_POSE, expand
from pac_host.diagnose.runs import Run
from pac_host.model.effects import Effect, step_moves
from pac_host.model.kinematics import integrate
from pac_host.model.table import measured_table


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
) -> list[Run]:
    """Run each turn cycle for ``n_cycles`` gait cycles in the world and observe it.

    Runs follow each other in sessions of ``runs_per_session`` after a power-on, so
    ``cycles_since_power_on`` grows within a session (what a battery effect acts on).
    """
    ids, _ = expand(np.asarray(turn_cycles), n_cycles)
    m = len(ids)
    n0 = (np.arange(m) % runs_per_session) * n_cycles
    body, world = step_moves(rows, ids, effects, n0)
    start = np.broadcast_to(np.asarray(start_pose, dtype=np.float64), (m, 3))
    poses = integrate(start, body, world)
    sd = np.array([pos_noise_cm, pos_noise_cm, heading_noise_deg])
    obs = poses + rng.normal(size=poses.shape) * sd
    return [Run(f"run{k:03d}", obs[k, 0], ids[k], obs[k, 1:], int(n0[k])) for k in range(m)]
