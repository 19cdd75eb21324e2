"""Coverage over noisy walks: what a robot with step noise delivers, compiled.

A real robot never walks the same gait cycle twice (:mod:`pac_host.model.step_noise`): each
executed gait cycle moves by its row plus ``sd * N(0, 1)`` per component, so a turn cycle has
no one coverage, only a distribution over walks. This module scores turn cycles by K noisy
walks with common random numbers: the caller draws standard normals z (K, budget, 3) once
(:func:`draw_normals`) and every turn cycle is walked with the same z (walk k's step t moves by
its row plus ``sd * z[k, t]``), so differences between turn cycles are not noise.

The compiled kernel (:func:`NoisyWalks.figures`) walks the K walks side by side (the walks in
the inner loop, over contiguous arrays) with the noise-free kernel's arithmetic
(:mod:`pac_host.coverage.kernel`: the heading as a running complex product, no sine or cosine
per step, its body-width test and figures): a step's rotation is the row's times the noise's,
``exp(-i (dH + sd z))`` = ``exp(-i dH) exp(-i sd z)``, the second tabulated once per (step, walk)
for each deviation in dH the table uses. With every deviation 0 it gives
:func:`~pac_host.coverage.simulate`'s figures value for value; :func:`reference_figures` is the
numpy noisy walk of :mod:`pac_host.coverage.walks` on the same normals, the tests' reference.

>>> from pac_host.model import shifted_table
>>> from pac_host.model.step_noise import parse_step_noise
>>> from pac_host.coverage.turn_cycle import parse_turn_cycle
>>> z = draw_normals(np.random.default_rng(0), 8, 200)
>>> walks = NoisyWalks(shifted_table().rows, parse_step_noise("0.3,1"), z)
>>> walks.figures(parse_turn_cycle("12:60,3:10")[None]).shape  # (figures, P, K)
(5, 1, 8)
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence

import numpy as np

from pac_host.coverage import kernel as coverage_jit
from pac_host.coverage.area import START_POSE
from pac_host.coverage.turn_cycle import DEFAULT_BUDGET, check_budget
from pac_host.coverage.walks import spread, walks_of_normals
from pac_host.errors import InputError
from pac_host.model.effects import (
    Effect,
    effective_rows,
    sequence_effects,
    world_drift,
)
from pac_host.model.kinematics import complex_moves, heading_rotation
from pac_host.model.step_noise import StepNoise

MAX_WALKS = 4096  # more walks than this measure nothing a few hundred do not
# walks x gait cycles the normals may hold (24 bytes each): 4,096 walks of 1,000 gait cycles
MAX_WALK_STEPS = 4096 * 1000
# a table with more distinct deviations in dH than this computes the noise's rotation per step
# rather than tabulate one (step, walk) table per deviation
_MAX_LEVELS = 4
_compiled = None


def check_walks(walks: int, budget: int, what: str = "--walks") -> int:
    """``walks`` as an int if it is a number of noisy walks worth drawing at ``budget``."""
    if isinstance(walks, bool) or not isinstance(walks, (int, np.integer)) or \
            not 1 <= walks <= MAX_WALKS:
        raise InputError(f"{what} must be an integer in 1..{MAX_WALKS}, got {walks}")
    if walks * max(int(budget), 1) > MAX_WALK_STEPS:
        raise InputError(f"{what} {walks} of {budget} gait cycles is more than "
                         f"{MAX_WALK_STEPS:,} noisy gait cycles; give fewer walks")
    return int(walks)


def check_quantile(quantile: float | None) -> float | None:
    """``quantile`` if it is None (the mean) or inside (0, 1)."""
    if quantile is not None and not (math.isfinite(quantile) and 0 < quantile < 1):
        raise InputError(f"--quantile must be inside (0, 1), got {quantile:g}")
    return quantile


def draw_normals(rng: np.random.Generator, walks: int, budget: int) -> np.ndarray:
    """Standard normals (walks, budget, 3) from ``rng``: walk k's gait cycle t moves by its
    row plus ``sd * z[k, t]`` (F, T, dH)."""
    return rng.standard_normal((check_walks(walks, budget, "walks"), budget, 3))


def _block(x: float, y: float, c: float, s: float) -> int:  # replaced by the kernel's, compiled
    raise NotImplementedError


def _figures(blocks, n, top, visits, first, out, k):  # replaced by the kernel's, compiled
    raise NotImplementedError


def _shared_steps(a, b, budget):  # replaced by the kernel's, compiled
    raise NotImplementedError


def _score_noisy(genes: np.ndarray, disp_r: np.ndarray, disp_i: np.ndarray, rot_r: np.ndarray,
                 rot_i: np.ndarray, sd_f: np.ndarray, sd_t: np.ndarray, sd_h: np.ndarray,
                 level: np.ndarray, zf: np.ndarray, zt: np.ndarray, zh: np.ndarray,
                 nrot_r: np.ndarray, nrot_i: np.ndarray, q0r: np.ndarray, q0i: np.ndarray,
                 p0r: np.ndarray, p0i: np.ndarray, drift_r: float, drift_i: float,
                 budget: int, state: np.ndarray, ints: np.ndarray) -> np.ndarray:
    """Figures (5, P * K) of turn cycles ``genes`` (P, G, 2) over K noisy walks: column
    ``p * K + k`` is turn cycle p's walk k.

    Gait id g moves by the row's displacement ``disp`` (T + i F) and rotation ``rot``
    (exp(-i dH)), split into real and imaginary parts (32,), plus the noise: walk k's gait
    cycle t adds ``sd_t[g] zt[t, k]`` to T and ``sd_f[g] zf[t, k]`` to F and turns by
    ``exp(-i sd_h[g] zh[t, k])`` more (radians), looked up in ``nrot[level[g], t, k]`` when
    ``level[g]`` >= 0, else computed. Walk k starts at position ``p0[k]`` with heading ``q0[k]``.

    The walks' state after each gait cycle t is row t of (budget + 1, K) arrays, which a step
    reads at t - 1 and writes at t, so it is kept for the next turn cycle at no cost: each
    turn cycle starts where it parts from the one before it, as the noise-free kernel's paths
    do (the gait cycles they walk alike, with the same normals, are not walked again).
    The loops index these arrays by (t, k) rather than take a row view per gait cycle: a
    view costs its reference counting at every step, and without it the stepping runs about
    20% faster (bench/bench_noisy.py), the same arithmetic. The caller keeps them from call to
    call: ``state`` (4, budget + 1, K) floats (q and p, real and imaginary parts) and ``ints``
    (4, budget + 1, K) (the blocks, their running highest, and in column 0 the gene walked
    at t and its repetitions walked by then), so a small batch does not pay for fresh pages."""
    n_genes = genes.shape[0]
    n_walks = zf.shape[1]
    out = np.empty((5, n_genes * n_walks), dtype=np.int64)
    qr, qi, pr, pi = state[0], state[1], state[2], state[3]
    blocks = ints[0]
    top = ints[1]  # the highest block detected by t
    js = ints[2, :, 0]  # the gene walked at t
    used = ints[3, :, 0]  # its repetitions walked by t
    visits = np.zeros(64, dtype=np.int64)
    first = np.zeros(64, dtype=np.int64)
    for k in range(n_walks):
        b = _block(p0r[k], p0i[k], q0r[k], q0i[k])
        blocks[0, k] = b
        qr[0, k] = q0r[k]
        qi[0, k] = q0i[k]
        pr[0, k] = p0r[k]
        pi[0, k] = p0i[k]
        top[0, k] = b
    for c in range(n_genes):
        g = genes[c]
        loop = 0
        for j in range(g.shape[0]):
            loop += g[j, 1]
        s = 0
        if c != 0:
            s = _shared_steps(g, genes[c - 1], budget)
        if s == 0:
            j = 0
            left = g[0, 1]
        else:
            j = js[s]
            left = g[j, 1] - used[s]
        for t in range(s + 1, budget + 1):
            u = t - 1
            if loop == 0:  # a turn cycle without repetitions stands still: no gait cycle
                for k in range(n_walks):
                    qr[t, k] = qr[u, k]
                    qi[t, k] = qi[u, k]
                    pr[t, k] = pr[u, k]
                    pi[t, k] = pi[u, k]
                    top[t, k] = top[u, k]
                    blocks[t, k] = blocks[u, k]
                continue
            while left == 0:
                j = (j + 1) % g.shape[0]
                left = g[j, 1]
            left -= 1
            js[t] = j
            used[t] = g[j, 1] - left
            gait = g[j, 0]
            dr = disp_r[gait]
            di = disp_i[gait]
            rr = rot_r[gait]
            ri = rot_i[gait]
            sf = sd_f[gait]
            st = sd_t[gait]
            lv = level[gait]
            # the step below stands twice, once per way to the noise's rotation (tabulated or
            # computed): an inlined helper for it measured 2.4x the plain walker against 5.2x
            # (bench_noisy, idle machine), as the loop over walks no longer vectorised
            if lv >= 0:
                for k in range(n_walks):
                    nr = nrot_r[lv, u, k]
                    ni = nrot_i[lv, u, k]
                    # the noisy move: displacement, then the rotation (row's times noise's)
                    mr = dr + st * zt[u, k]
                    mi = di + sf * zf[u, k]
                    wr = rr * nr - ri * ni
                    wi = rr * ni + ri * nr
                    # as the noise-free kernel: step = d q; q = q r; p = p + (step + drift)
                    a0 = qr[u, k]
                    e0 = qi[u, k]
                    sr = mr * a0 - mi * e0
                    si = mr * e0 + mi * a0
                    a = a0 * wr - e0 * wi
                    e = a0 * wi + e0 * wr
                    x = pr[u, k] + (sr + drift_r)
                    y = pi[u, k] + (si + drift_i)
                    qr[t, k] = a
                    qi[t, k] = e
                    pr[t, k] = x
                    pi[t, k] = y
                    b = _block(x, y, a, e)
                    blocks[t, k] = b
                    top[t, k] = max(top[u, k], b)
            else:
                sh = sd_h[gait]
                for k in range(n_walks):
                    ang = -(sh * zh[u, k])
                    nr = math.cos(ang)
                    ni = math.sin(ang)
                    mr = dr + st * zt[u, k]
                    mi = di + sf * zf[u, k]
                    wr = rr * nr - ri * ni
                    wi = rr * ni + ri * nr
                    a0 = qr[u, k]
                    e0 = qi[u, k]
                    sr = mr * a0 - mi * e0
                    si = mr * e0 + mi * a0
                    a = a0 * wr - e0 * wi
                    e = a0 * wi + e0 * wr
                    x = pr[u, k] + (sr + drift_r)
                    y = pi[u, k] + (si + drift_i)
                    qr[t, k] = a
                    qi[t, k] = e
                    pr[t, k] = x
                    pi[t, k] = y
                    b = _block(x, y, a, e)
                    blocks[t, k] = b
                    top[t, k] = max(top[u, k], b)
        for k in range(n_walks):
            visits, first = _figures(blocks[:, k], budget + 1, top[budget, k], visits, first,
                                     out, c * n_walks + k)
    return out


def _compile():
    """The kernel compiled, with the noise-free kernel's helpers (cached on disk by numba)."""
    global _compiled, _block, _figures, _shared_steps
    if _compiled is None:
        import numba

        coverage_jit._compile()
        _block, _figures = coverage_jit._block, coverage_jit._figures
        _shared_steps = coverage_jit._shared_steps
        _compiled = numba.njit(cache=True, nogil=True)(_score_noisy)
    return _compiled


class NoisyWalks:
    """K noisy walks of turn cycles on one gait table, prepared once: the table's moves, the
    noise's deviations per gait id and its rotations tabulated per (step, walk), the start
    poses. :meth:`figures` scores batches of turn cycles on them (a search's thousands).

    ``z`` (K, budget, 3): standard normals (:func:`draw_normals`); ``starts``: one start pose
    (3,) or one per walk (K, 3) (a robot placed by hand: placement error and step noise
    compose). Effects that depend on the executed sequence (``transition``, ``battery_sag``,
    user-defined) are walked by the numpy reference, :func:`reference_figures`."""

    def __init__(self, rows: np.ndarray, noise: StepNoise, z: np.ndarray,
                 budget: int | None = None, effects: Sequence[Effect] = (),
                 starts: Sequence[float] | np.ndarray = START_POSE) -> None:
        z = np.asarray(z, dtype=np.float64)
        if z.ndim != 3 or z.shape[2] != 3:
            raise ValueError(f"normals must be (walks, budget, 3), got {z.shape}")
        self.budget = check_budget(z.shape[1] if budget is None else budget)
        if z.shape[1] < self.budget:
            raise ValueError(f"normals for {z.shape[1]} gait cycles, budget {self.budget}")
        self.walks = z.shape[0]
        self.rows = np.asarray(rows, dtype=np.float64)
        self.noise, self.effects, self.z = noise, tuple(effects), z
        starts = np.asarray(starts, dtype=np.float64)
        self.starts = np.broadcast_to(starts, (self.walks, 3)) if starts.ndim == 1 else starts
        if self.starts.shape != (self.walks, 3):
            raise ValueError(f"start poses {starts.shape}, expected (3,) or ({self.walks}, 3)")
        self.compiled = coverage_jit.AVAILABLE and not sequence_effects(self.effects)
        self._scratch = threading.local()
        if self.compiled:
            self._prepare()

    def _prepare(self) -> None:
        table = effective_rows(self.rows, self.effects)
        moves = complex_moves(table)
        sd = self.noise.sd
        b = self.budget
        zt = self.z[:, :b].transpose(1, 2, 0)  # (budget, 3, K): the walks contiguous
        self._z = [np.ascontiguousarray(zt[:, i]) for i in range(3)]
        levels = np.unique(sd[:, 2])
        level = np.full(32, -1, dtype=np.int64)
        nrot = np.ones((0, b, self.walks), dtype=np.complex128)
        if len(levels) <= _MAX_LEVELS:
            level = np.searchsorted(levels, sd[:, 2]).astype(np.int64)
            nrot = np.exp(-1j * np.radians(levels[:, None, None] * self._z[2][None]))
        drift = world_drift(self.effects)
        q0 = heading_rotation(self.starts[:, 2])
        self._args = (
            np.ascontiguousarray(moves[:, 0].real), np.ascontiguousarray(moves[:, 0].imag),
            np.ascontiguousarray(moves[:, 1].real), np.ascontiguousarray(moves[:, 1].imag),
            np.ascontiguousarray(sd[:, 0]), np.ascontiguousarray(sd[:, 1]),
            np.radians(sd[:, 2]), level, *self._z,
            np.ascontiguousarray(nrot.real), np.ascontiguousarray(nrot.imag),
            np.ascontiguousarray(q0.real), np.ascontiguousarray(q0.imag),
            np.ascontiguousarray(self.starts[:, 0]), np.ascontiguousarray(self.starts[:, 1]),
            0.0 if drift is None else float(drift[0]), 0.0 if drift is None else float(drift[1]),
            self.budget)

    def figures(self, genes: np.ndarray) -> np.ndarray:
        """Figures (5, P, K) of turn cycles (P, G, 2): (covered, covered once, fitness, repeat
        visits, reached at) of each turn cycle's walk k."""
        genes = np.ascontiguousarray(genes, dtype=np.int64)
        if genes.ndim == 2:
            genes = genes[None]
        if not self.compiled:
            return reference_figures(self.rows, genes, self.noise, self.z, self.budget,
                                     self.effects, self.starts)
        scratch = getattr(self._scratch, "arrays", None)
        if scratch is None:  # one set per thread (the kernel releases the GIL)
            shape = (4, self.budget + 1, self.walks)
            scratch = self._scratch.arrays = (np.empty(shape), np.empty(shape, dtype=np.int64))
        out = _compile()(genes, *self._args, *scratch)
        return out.reshape(5, genes.shape[0], self.walks)


class NoisyScorer:
    """A search's scores of turn cycles over K noisy walks with common random numbers
    (:class:`NoisyWalks`): :meth:`both` gives :func:`noisy_search_score` (the mean fitness, or
    a ``quantile`` of it, first) twice, as :class:`~pac_host.coverage.Scorer` gives its
    search scores and scores."""

    def __init__(self, rows: np.ndarray, noise: StepNoise, z: np.ndarray,
                 budget: int = DEFAULT_BUDGET, effects: Sequence[Effect] = (),
                 starts: Sequence[float] | np.ndarray = START_POSE,
                 quantile: float | None = None) -> None:
        self._walks = NoisyWalks(rows, noise, z, budget, effects, starts)
        self.budget, self.quantile = self._walks.budget, check_quantile(quantile)
        self.walks = self._walks.walks  # walks a turn cycle costs

    def both(self, genes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Search scores (P,) of turn cycles (P, G, 2), twice."""
        f = self._walks.figures(genes)
        keys = noisy_search_score(f[2], f[4], self.budget, self.quantile)
        return keys, keys

    def fitness(self, score: int) -> float:
        """The mean fitness (or the quantile) inside one of these scores."""
        return float(fitness_of_noisy_score(score, self.budget, self.walks, self.quantile))


def reference_figures(rows: np.ndarray, genes: np.ndarray, noise: StepNoise, z: np.ndarray,
                      budget: int = DEFAULT_BUDGET, effects: Sequence[Effect] = (),
                      starts: Sequence[float] | np.ndarray = START_POSE) -> np.ndarray:
    """Figures (5, P, K) of turn cycles (P, G, 2) over K noisy walks, the straightforward way
    (the reference the kernel is tested against): the numpy noisy walk
    (:func:`~pac_host.coverage.walks.walks_of_normals`, each walk's moves the rows after the
    effects plus ``sd * z``, integrated by the model's pose update) with walk k's normals
    shared by every turn cycle."""
    genes = np.asarray(genes, dtype=np.int64)
    if genes.ndim == 2:
        genes = genes[None]
    z = np.asarray(z, dtype=np.float64)[:, None, :budget]  # (K, 1, budget, 3)
    starts = np.broadcast_to(np.asarray(starts, dtype=np.float64), (z.shape[0], 3))
    cov = walks_of_normals(rows, genes, budget, effects, noise, z, starts[:, None])
    figures = (cov.blocks_covered, cov.blocks_covered_once, cov.fitness, cov.repeat_visits,
               cov.reached_at)
    return np.stack([np.moveaxis(f, 0, 1) for f in figures])  # (5, P, K)


def noisy_search_score(fitness: np.ndarray, reached_at: np.ndarray, budget: int,
                       quantile: float | None = None) -> np.ndarray:
    """A search's ranking (P,) of turn cycles by their walks' figures (P, K): with ``quantile``
    None, the summed fitness (the mean's), then the fitness reached in fewer gait cycles
    (summed); with one, the walks' ``quantile`` fitness (the lower sample quantile, one walk's),
    then the summed fitness. :func:`fitness_of_noisy_score` reads the mean or quantile back.

    >>> f, r = np.array([[7, 5]]), np.array([[150, 90]])
    >>> fitness_of_noisy_score(noisy_search_score(f, r, 200), 200, 2).tolist()
    [6.0]
    >>> fitness_of_noisy_score(noisy_search_score(f, r, 200, 0.25), 200, 2, 0.25).tolist()
    [5.0]
    """
    fitness = np.asarray(fitness, dtype=np.int64)
    k = fitness.shape[-1]
    total = fitness.sum(axis=-1)
    if quantile is None:
        slack = k * budget - np.asarray(reached_at, dtype=np.int64).sum(axis=-1)
        return total * (k * budget + 1) + slack
    q = np.quantile(fitness, quantile, axis=-1, method="inverted_cdf").astype(np.int64)
    return q * (k * (budget + 1) + 1) + total  # a fitness is at most budget + 1 blocks


def fitness_of_noisy_score(score: np.ndarray | int, budget: int, walks: int,
                           quantile: float | None = None) -> np.ndarray | float:
    """The mean fitness (or the quantile) inside a :func:`noisy_search_score` of ``walks``
    walks."""
    score = np.asarray(score, dtype=np.int64)
    if quantile is None:
        return (score // (walks * budget + 1)) / walks
    return (score // (walks * (budget + 1) + 1)).astype(np.float64)


def summary(fitness: np.ndarray) -> dict:
    """Mean fitness over walks with its 95% interval (normal approximation), the walks, the
    median and 10th percentile (JSON-ready): :func:`~pac_host.coverage.walks.spread`'s figures
    with the interval."""
    f = np.asarray(fitness, dtype=np.float64).ravel()
    half = 1.96 * float(f.std(ddof=1)) / math.sqrt(f.size) if f.size > 1 else 0.0
    s = spread(f, digits=3)
    return {"walks": int(f.size), "mean": s["mean"],
            "ci95": [round(float(f.mean()) - half, 3), round(float(f.mean()) + half, 3)],
            "median": s["median"], "p10": s["p10"]}
