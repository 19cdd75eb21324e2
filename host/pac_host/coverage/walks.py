"""Noisy walks: a turn cycle walked by a robot whose every gait cycle varies (step noise).

The figures of one noise-free walk are :func:`~pac_host.coverage.simulate`'s; with step noise
each walk wanders differently, so a turn cycle has a distribution of figures, summarised by
:func:`spread`. :func:`walks_of_normals` is the one numpy noisy walk: each walk's moves are its
rows plus the noise of given standard normals, integrated and scored like an observed path;
:func:`noisy_walks` draws the normals, and the compiled kernel's reference
(:func:`pac_host.coverage.noisy.reference_figures`) shares them between turn cycles.

>>> import numpy as np
>>> from pac_host.model import measured_table
>>> from pac_host.model.step_noise import parse_step_noise
>>> from pac_host.coverage import parse_turn_cycle
>>> genes = np.broadcast_to(parse_turn_cycle("12:14,3:10"), (4, 9, 2))
>>> cov = noisy_walks(measured_table().rows, genes, 200, (), parse_step_noise("0.3,1"),
...                   np.random.default_rng(0))
>>> cov.fitness.shape
(4,)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from pac_host.coverage.area import START_POSE
from pac_host.coverage.scores import Coverage, coverage_of_poses
from pac_host.coverage.turn_cycle import check_budget, expand
from pac_host.model.effects import Effect, step_moves
from pac_host.model.kinematics import integrate
from pac_host.model.step_noise import StepNoise


def noisy_walks(
    rows: np.ndarray,
    genes: np.ndarray,
    budget: int,
    effects: Sequence[Effect],
    noise: StepNoise,
    rng: np.random.Generator,
    start_poses: Sequence[float] | np.ndarray = START_POSE,
    keep_paths: bool = False,
) -> Coverage:
    """One walk of each turn cycle of ``genes`` (P, G, 2) or (G, 2) on ``rows`` (32, 3) for
    ``budget`` gait cycles, each gait cycle's move drawn with ``noise`` from ``rng``, from
    ``start_poses`` (3,) or one per walk (P, 3). Figures (P,); poses and blocks when
    ``keep_paths``. Random user-defined effects give their expected move, as in ``simulate``.
    """
    budget = check_budget(budget)
    genes = np.asarray(genes, dtype=np.int64)
    genes = genes[None] if genes.ndim == 2 else genes
    ids, _ = expand(genes, budget)
    if noise.is_zero():  # draws nothing
        return walks_of_normals(rows, genes, budget, effects, noise, None, start_poses,
                                keep_paths)
    if rng is None:
        raise ValueError("step noise needs a Generator to draw from")
    z = rng.standard_normal(ids.shape + (3,))  # as StepNoise.draw
    return walks_of_normals(rows, genes, budget, effects, noise, z, start_poses, keep_paths)


def walks_of_normals(
    rows: np.ndarray,
    genes: np.ndarray,
    budget: int,
    effects: Sequence[Effect],
    noise: StepNoise,
    z: np.ndarray | None,
    start_poses: Sequence[float] | np.ndarray = START_POSE,
    keep_paths: bool = False,
) -> Coverage:
    """The noisy walks of turn cycles ``genes`` (P, G, 2) given their standard normals ``z``
    (..., P, budget, 3) (None: no noise): gait cycle t of a walk moves by its row after the
    ``effects`` plus ``noise.errors`` of ``z[..., t, :]``, integrated from ``start_poses``
    (broadcast against (..., P, 3)) by :func:`~pac_host.model.kinematics.integrate`. Figures
    (..., P). The one noisy walk in numpy: :func:`noisy_walks` draws ``z``, and the compiled
    kernel's reference (:func:`pac_host.coverage.noisy.reference_figures`) shares it
    between turn cycles."""
    ids, still = expand(genes, budget)
    body, world = step_moves(rows, ids, effects)
    if z is not None:
        body = body + noise.errors(ids, z)
    body = np.array(np.broadcast_to(body, np.broadcast_shapes(body.shape, (
        () if z is None else np.shape(z)))))
    body[..., still, :, :] = 0.0  # a turn cycle with no repetitions stands still
    if world is not None:
        world = np.array(np.broadcast_to(world, body.shape[:-1] + (2,)))
        world[..., still, :, :] = 0.0
    poses = integrate(np.asarray(start_poses, dtype=np.float64), body, world)
    return coverage_of_poses(poses, keep=keep_paths)


CHUNK_STEPS = 1_000_000  # gait cycles integrated at once (about 100 MB of scratch)


def walk_many(
    rows: np.ndarray,
    genes: np.ndarray,
    n: int,
    budget: int,
    effects: Sequence[Effect],
    noise: StepNoise,
    rng: np.random.Generator,
    start_poses: np.ndarray | None = None,
    keep: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[Coverage, np.ndarray]:
    """``n`` noisy walks of one turn cycle ``genes`` (G, 2), in chunks: their figures (n,)
    and the poses of the first ``keep`` walks (keep, budget + 1, 3). ``start_poses`` (n, 3):
    one per walk (None: all from the start pose). ``progress(done, total)`` hears each chunk.
    """
    genes = np.asarray(genes, dtype=np.int64)
    chunk = max(1, CHUNK_STEPS // (budget + 1))
    figures: list[list[np.ndarray]] = []
    kept: list[np.ndarray] = []
    for lo in range(0, n, chunk):
        hi = min(lo + chunk, n)
        starts = START_POSE if start_poses is None else start_poses[lo:hi]
        cov = noisy_walks(rows, np.broadcast_to(genes, (hi - lo,) + genes.shape), budget,
                          effects, noise, rng, starts, keep_paths=lo < keep)
        figures.append([cov.blocks_covered, cov.blocks_covered_once, cov.fitness,
                        cov.repeat_visits, cov.reached_at])
        if lo < keep:
            kept.append(cov.poses[: keep - lo])
        if progress is not None:
            progress(hi, n)
    total = Coverage(*(np.concatenate(f) for f in zip(*figures, strict=True)))
    return total, (np.concatenate(kept) if kept else np.empty((0, budget + 1, 3)))


def spread(values: np.ndarray, digits: int = 2) -> dict:
    """Mean (to ``digits``), median, 10th and 90th percentiles of one figure over walks
    (JSON-ready): the one summary of noisy walks (``simulate --walks``; with its interval,
    :func:`pac_host.coverage.noisy.summary`).

    >>> spread(np.arange(11))
    {'mean': 5.0, 'median': 5.0, 'p10': 1.0, 'p90': 9.0}
    """
    v = np.asarray(values, dtype=np.float64)
    return {"mean": round(float(v.mean()), digits), "median": float(np.median(v)),
            "p10": float(np.percentile(v, 10)), "p90": float(np.percentile(v, 90))}
