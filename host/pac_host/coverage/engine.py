"""The coverage simulator's engine (DESIGN.md 2.3): the hot loop of everything.

Runs whole populations of turn cycles on one or many gait tables at once with numpy (or the
compiled kernel, :mod:`pac_host.coverage.kernel`, value for value), and scores each path
(:mod:`pac_host.coverage.scores`). Detection is checked at the start pose and after every gait
cycle.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from pac_host.coverage import kernel as coverage_jit
from pac_host.coverage.area import START_POSE, _detect, _DetectScratch
from pac_host.coverage.scores import (
    Coverage,
    coverage_score,
    figures_from_blocks,
    pooled_search_score,
    search_score,
)
from pac_host.coverage.turn_cycle import (
    _FIRST_GENE,
    _ONE,
    _START,
    DEFAULT_BUDGET,
    MAX_GENES,
    _step_entries,
    check_budget,
)
from pac_host.model.effects import (
    Effect,
    effective_rows,
    sag_factor,
    sequence_effects,
    step_moves,
    world_drift,
)
from pac_host.model.kinematics import (
    accumulate_headings,
    complex_moves,
    heading_rotation,
    integrate_path,
    scan_moves,
)


class _Workspace(_DetectScratch):
    """Scratch arrays for one (paths, budget) shape, reused chunk after chunk: allocating them
    afresh costs more in page faults than the arithmetic done in them."""

    def __init__(self, shape: tuple[int, int]) -> None:
        n_paths, budget = shape
        poses = (n_paths, budget + 1)
        super().__init__(poses)
        self.q = np.empty((n_paths, budget + 2), dtype=np.complex128)
        self.p = np.empty(poses, dtype=np.complex128)
        self.steps = np.empty((n_paths, budget + 2), dtype=np.intp)
        self.steps[:, 0], self.steps[:, 1] = _ONE, _START
        self.pos = np.empty(shape, dtype=np.intp)
        self.first = np.empty(shape, dtype=np.intp)
        self.gene_rot = np.empty(_FIRST_GENE + n_paths * MAX_GENES, dtype=np.complex128)
        self.gene_disp = np.empty_like(self.gene_rot)
        self.prev = np.empty(poses, dtype=np.int64)


_local = threading.local()

# With battery_sag, the compiled kernel's moves tabulated per step (per gait id and, with a
# transition, per pair of gait ids) may take up to this many bytes; more runs in numpy.
_TABULATED_BYTES = 256 * 2**20


def _workspace(shape: tuple[int, int]) -> _Workspace:
    cache = _local.__dict__.setdefault("cache", {})
    ws = cache.get(shape)
    if ws is None:
        if len(cache) >= 8:
            cache.clear()
        ws = cache[shape] = _Workspace(shape)
    return ws


# Paths per inner batch, measured: 128 beats 64 by about 10% (fewer numpy calls per path) and
# 256 or more gains nothing, as the chunk's scratch arrays (about 3 MB) outgrow the cache.
CHUNK_PATHS = 128


def simulate(
    rows: np.ndarray,
    genes: np.ndarray,
    budget: int = DEFAULT_BUDGET,
    effects: Sequence[Effect] = (),
    start_pose: Sequence[float] = START_POSE,
    keep_paths: bool = False,
    kernel: str = "auto",
) -> Coverage:
    """Run turn cycles on gait tables and score the paths.

    ``rows`` is one table (32, 3) or M tables (M, 32, 3); ``genes`` is one turn cycle (9, 2) or
    P of them (P, 9, 2). The result's arrays have shape (P,) for one table, (M, P) for M.
    ``kernel``: ``"numpy"`` (the reference), ``"numba"`` (compiled, the same figures value for
    value; only for scores without kept paths, and with no sequence effects but the built-in
    ``transition`` and ``battery_sag``) or ``"auto"`` (numba where it applies and is
    installed). User-defined effects run in numpy, and so does ``battery_sag`` when its moves
    tabulated per step would take more than 256 MB (many tables and a long budget).
    """
    budget = check_budget(budget)
    rows = np.asarray(rows, dtype=np.float64)
    genes = np.asarray(genes, dtype=np.int64)
    if genes.ndim == 2:
        genes = genes[None]
    n_tables = 1 if rows.ndim == 2 else rows.shape[0]
    n_genes = genes.shape[0]
    n_paths = n_tables * n_genes
    run = _Runner(rows, budget, tuple(effects), np.asarray(start_pose, dtype=np.float64),
                  keep_paths)
    compiled = not keep_paths and run.compiled and coverage_jit.AVAILABLE
    if kernel == "numba" and not compiled:
        raise ValueError("the numba kernel needs numba, no kept paths and no sequence effects "
                         "but transition and battery_sag (user-defined effects run in numpy)")
    if compiled and kernel == "auto":
        compiled = run.tabulating_pays(genes)
    if compiled and kernel != "numpy":
        figures = run.score_compiled(genes, n_tables)
        shape = (n_genes,) if rows.ndim == 2 else (n_tables, n_genes)
        return Coverage(*(f.reshape(shape) for f in figures))
    figures = np.empty((5, n_paths), dtype=np.int64)
    poses = np.empty((n_paths, budget + 1, 3)) if keep_paths else None
    blocks = np.empty((n_paths, budget + 1), dtype=np.int64) if keep_paths else None
    for lo in range(0, n_paths, CHUNK_PATHS):
        hi = min(lo + CHUNK_PATHS, n_paths)
        if rows.ndim == 2:
            ws, h = run.chunk(genes[lo:hi], None)
        else:
            k = np.arange(lo, hi)
            ws, h = run.chunk(genes[k % n_genes], k // n_genes)
        figures[:, lo:hi] = figures_from_blocks(ws.blocks, ws.prev)
        if keep_paths:
            poses[lo:hi] = np.stack((ws.p.real, ws.p.imag, h), axis=-1)
            blocks[lo:hi] = ws.blocks
    shape = (n_genes,) if rows.ndim == 2 else (n_tables, n_genes)
    if keep_paths:
        poses = poses.reshape(shape + poses.shape[1:])
        blocks = blocks.reshape(shape + blocks.shape[1:])
    return Coverage(*(f.reshape(shape) for f in figures), poses, blocks)


class Scorer:
    """Scores (:meth:`Coverage.score`) of batches of turn cycles on one gait table, with
    :func:`simulate`'s setup (effective rows, moves) done once: a search scores thousands of
    small batches on the same model. The scores are simulate's, value for value.

    ``start_pose`` is one pose (3,) or K of them (K, 3): with K, each turn cycle is walked from
    every one and :meth:`both`'s search scores are pooled over the walks
    (:func:`pooled_search_score`; :mod:`pac_host.coverage.placement` makes such poses). ``models``
    (M, 32, 3), other tables the robot may be (draws from a model's posterior), are walked
    too, from every start pose, and pooled the same way: a turn cycle that relies on rows the
    tables disagree on scores lower.

    >>> from pac_host.coverage.turn_cycle import parse_turn_cycle
    >>> from pac_host.model import shifted_table
    >>> genes = parse_turn_cycle("12:60,3:10")
    >>> bool(Scorer(shifted_table().rows)(genes[None])[0]
    ...      == simulate(shifted_table().rows, genes).score()[0])
    True
    """

    def __init__(self, rows: np.ndarray, budget: int = DEFAULT_BUDGET,
                 effects: Sequence[Effect] = (),
                 start_pose: Sequence[float] = START_POSE,
                 models: np.ndarray | None = None) -> None:
        self.rows = np.asarray(rows, dtype=np.float64)
        self.budget, self.effects = check_budget(budget), tuple(effects)
        self.start_pose = np.asarray(start_pose, dtype=np.float64)
        self.starts = np.atleast_2d(self.start_pose)
        tables = [self.rows]
        if models is not None:
            tables += list(np.asarray(models, dtype=np.float64).reshape(-1, *self.rows.shape))
        # every walk a turn cycle gets: each table from each start pose, the given table
        # from the first pose first
        self._walks = [(t, p) for t in tables for p in self.starts]
        self._runs = [_Runner(t, self.budget, self.effects, p, False) for t, p in self._walks]
        self._run = self._runs[0]
        self._compiled = (self.rows.ndim == 2 and self._run.compiled
                          and coverage_jit.AVAILABLE)

    @property
    def walks(self) -> int:
        """Walks a turn cycle costs: start poses times tables."""
        return len(self._walks)

    def __call__(self, genes: np.ndarray) -> np.ndarray:
        """Scores (P,) of turn cycles (P, 9, 2)."""
        return self.both(genes)[1]

    def both(self, genes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Search scores (:func:`search_score`) and scores, (P,) each, of turn cycles
        (P, 9, 2). Over several walks (start poses, tables): the pooled search scores, and the
        scores of the walks on the given table from the first pose."""
        genes = np.asarray(genes, dtype=np.int64)
        walks = []
        for run, (table, pose) in zip(self._runs, self._walks, strict=True):
            if self._compiled:
                _, _, fitness, repeat, reached = run.score_compiled(genes, 1)
            else:
                cov = simulate(table, genes, self.budget, self.effects, pose)
                fitness, repeat, reached = cov.fitness, cov.repeat_visits, cov.reached_at
            walks.append((fitness, reached, repeat))
        fitness, reached, repeat = walks[0]
        if len(walks) == 1:
            return (search_score(fitness, reached, repeat, self.budget),
                    coverage_score(fitness, repeat))
        pooled = pooled_search_score(*(np.stack(w) for w in zip(*walks, strict=True)),
                                     self.budget)
        return pooled, coverage_score(fitness, repeat)


class _Runner:
    """Runs chunks of paths on one table or a batch of tables, with the moves looked up per
    gene: when the effects depend on the gait id alone, a path's moves are its genes' rows."""

    def __init__(self, rows: np.ndarray, budget: int, effects: tuple[Effect, ...],
                 start: np.ndarray, keep: bool) -> None:
        self.rows, self.budget, self.effects, self.keep = rows, budget, effects, keep
        self.start = start
        self.q0 = heading_rotation(start[2])
        self.p0 = start[0] + 1j * start[1]
        self.h0 = start[2]
        # the compiled kernel runs table effects, a world drift, one built-in transition, whose
        # blend depends on the gait id and the one before (tabulated per pair of ids), and one
        # built-in battery_sag, whose moves depend on the step too (tabulated per step)
        seq = sequence_effects(effects)
        self.sequence = bool(seq)
        names = [e.name for e in seq]
        self.compiled = (len(set(names)) == len(names)
                         and set(names) <= {"transition", "battery_sag"})
        params = {e.name: e.params for e in seq} if self.compiled else {}
        self.alpha = params.get("transition", {}).get("alpha", 0.0)
        beta = params.get("battery_sag", {}).get("beta", 0.0)
        self.factor = None
        if self.compiled and beta > 0 and budget > 0:
            # step_moves' factor at each step of a run from power-on (n0 = 0), up to the first
            # step it reaches 0: every later step moves as that one
            factor = sag_factor(beta, 0, budget)
            zero = np.flatnonzero(factor == 0.0)
            self.factor = factor[: zero[0] + 1] if zero.size else factor
            n_tables = 1 if rows.ndim == 2 else rows.shape[0]
            entries = 32 + (32 * 32 if self.alpha > 0 else 0)  # gait ids, pairs of them
            self.compiled = n_tables * len(self.factor) * entries * 32 <= _TABULATED_BYTES
        if self.compiled:
            self.table = effective_rows(rows, effects)
            table = self.table.reshape(-1, 3)
            self.moves = complex_moves(table)
            self.turns = table[:, 2]
            drift = world_drift(effects)
            self.drift = None if drift is None else complex(drift[0], drift[1])
        if self.compiled and self.factor is not None:
            # the moves per table, gait id (or slot of a pair of ids) and step, filled in as
            # turn cycles use them (a search's batches use few of the pairs)
            shape = (len(self.table.reshape(-1, 32, 3)), 32, len(self.factor))
            self._rot = self._disp = None  # allocated when first needed
            self._shape = shape
            self._filled = np.zeros(32, dtype=bool)
            self._slots = np.full(32 * 32, -1, dtype=np.int64)
            self._n_pairs = 0
            self._lock = threading.Lock()
            self._blend_rot = self._blend_disp = np.empty((shape[0], 0, shape[2]),
                                                          dtype=np.complex128)

    def score_compiled(self, genes: np.ndarray, n_tables: int) -> np.ndarray:
        """Figures (5, n_tables * P) of turn cycles (P, G, 2) from the compiled kernel."""
        if self.factor is None:
            return coverage_jit.score_paths(genes, n_tables, self.moves, self.q0, self.p0,
                                            self.drift, self.budget,
                                            self.transition_moves(genes))
        with self._lock:  # a slot once filled keeps its place and moves: the kernel may run
            self.tabulate_steps(genes)  # while another thread fills in others
            blend_rot, blend_disp = self._blend_rot, self._blend_disp
        return coverage_jit.score_tabulated(
            genes, n_tables, self._rot.ravel(), self._disp.ravel(), len(self.factor), self.q0,
            self.p0, self.drift, self.budget, self._slots, blend_rot.shape[1],
            blend_rot.ravel(), blend_disp.ravel())

    def tabulating_pays(self, genes: np.ndarray) -> bool:
        """Whether the compiled kernel is worth its tabulation for turn cycles (P, G, 2) on
        this runner's tables: with ``battery_sag`` it converts each new gait id's (and pair's)
        move at every step, which costs more than numpy walking a handful of turn cycles on many
        tables (a model GA's tests); a search's scorer keeps its tables and never asks."""
        if self.factor is None:
            return True
        ids, pairs = self._untabulated(genes)
        return (len(ids) + len(pairs)) * len(self.factor) <= 4 * len(genes) * self.budget

    def _untabulated(self, genes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gait ids (k,) and, with a transition, the changes of gait id (n, 2) that turn
        cycles (P, G, 2) walk and whose moves per step are not tabulated yet."""
        genes = np.asarray(genes, dtype=np.int64)
        ids = np.unique(genes[..., 0][genes[..., 1] > 0])
        ids = ids[~self._filled[ids]]
        if self.alpha <= 0:
            return ids, np.zeros((0, 2), dtype=np.int64)
        pairs = coverage_jit.transition_pairs(genes)
        return ids, pairs[self._slots[pairs[:, 0] * 32 + pairs[:, 1]] < 0]

    def _per_step(self, body: np.ndarray) -> np.ndarray:
        """Complex moves (M, k, n_steps, 2) of body moves (..., k, 3) at each tabulated step,
        scaled as ``effects.step_moves`` scales them (after a transition's blend) and converted
        as ``integrate_path`` converts them, so the figures stay those of the numpy path value
        for value."""
        moves = complex_moves(body[..., None, :] * self.factor[:, None])
        return moves.reshape(self._shape[0], -1, len(self.factor), 2)

    def tabulate_steps(self, genes: np.ndarray) -> None:
        """With ``battery_sag``, for the compiled kernel: fill in the moves per step of the gait
        ids (and, with a transition, of the changes of gait id) turn cycles (P, G, 2) walk."""
        if self._rot is None:
            self._rot = np.empty(self._shape, dtype=np.complex128)
            self._disp = np.empty(self._shape, dtype=np.complex128)
        new, pairs = self._untabulated(genes)
        if new.size:
            moves = self._per_step(self.table[..., new, :])
            self._disp[:, new], self._rot[:, new] = moves[..., 0], moves[..., 1]
            self._filled[new] = True
        if not len(pairs):
            return
        lo, hi = self._n_pairs, self._n_pairs + len(pairs)
        if hi > self._blend_rot.shape[1]:  # grow the slots, keeping those filled
            size = min(32 * 32, max(hi, 2 * self._blend_rot.shape[1], 64))
            grown = []
            for old in (self._blend_rot, self._blend_disp):
                a = np.empty((old.shape[0], size, old.shape[2]), dtype=np.complex128)
                a[:, :lo] = old[:, :lo]
                grown.append(a)
            self._blend_rot, self._blend_disp = grown
        a = self.alpha
        prev, cur = self.table[..., pairs[:, 0], :], self.table[..., pairs[:, 1], :]
        moves = self._per_step((1 - a) * cur + a * prev)
        self._blend_disp[:, lo:hi], self._blend_rot[:, lo:hi] = moves[..., 0], moves[..., 1]
        self._slots[pairs[:, 0] * 32 + pairs[:, 1]] = np.arange(lo, hi)
        self._n_pairs = hi

    def transition_moves(self, genes: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """For the compiled kernel: the changes of gait id (prev, gait) the turn cycles make
        (n, 2) and, per table and change, the complex move of the transition's blended gait
        cycle (M * n, 2), blended from the table-effect rows as ``effects.step_moves`` blends
        them and converted as ``integrate_path`` converts them, so the figures stay those of
        the numpy path value for value. None without a transition (alpha 0 blends nothing)."""
        if self.alpha <= 0:
            return None
        pairs = coverage_jit.transition_pairs(genes)
        a = self.alpha
        prev, cur = self.table[..., pairs[:, 0], :], self.table[..., pairs[:, 1], :]
        return pairs, complex_moves((1 - a) * cur + a * prev).reshape(-1, 2)

    def chunk(self, genes: np.ndarray, tables: np.ndarray | None
              ) -> tuple[_Workspace, np.ndarray | None]:
        """Integrate and detect a chunk of paths (genes (P, G, 2), one table index per path or
        None for the single table); returns the workspace holding them, and the headings
        when paths are kept."""
        n = genes.shape[0]
        ws = _workspace((n, self.budget))
        still = _step_entries(genes, self.budget, ws.steps[:, 2:], ws.pos, ws.first)
        if self.sequence:
            heads = self._sequence_moves(genes[..., 0], tables, still, ws)
        else:
            ids = genes[..., 0] if tables is None else genes[..., 0] + 32 * tables[:, None]
            heads = self._table_moves(ids.ravel(), still, ws)
        q = ws.q[:, 1:]
        _detect(ws.p.real, ws.p.imag, q.imag, q.real, ws)
        return ws, heads

    def _table_moves(self, ids: np.ndarray, still: np.ndarray, ws: _Workspace
                     ) -> np.ndarray | None:
        end = _FIRST_GENE + ids.size
        rot, disp = ws.gene_rot[:end], ws.gene_disp[:end]
        rot[:_FIRST_GENE] = 1.0, self.q0, 1.0
        disp[:_FIRST_GENE] = self.p0, self.p0, 0.0
        np.take(self.moves[:, 1], ids, out=rot[_FIRST_GENE:])
        np.take(self.moves[:, 0], ids, out=disp[_FIRST_GENE:])
        np.take(rot, ws.steps, out=ws.q, mode="clip")
        np.take(disp, ws.steps[:, 1:], out=ws.p, mode="clip")
        drift = self.drift
        if drift is not None and still.any():
            drift = np.where(still, 0.0, drift)[:, None]
        scan_moves(ws.q, ws.p, drift)
        if not self.keep:
            return None
        turns = np.concatenate((np.zeros(_FIRST_GENE), self.turns[ids]))
        return accumulate_headings(self.h0, turns[ws.steps[:, 2:]])

    def _sequence_moves(self, ids: np.ndarray, tables: np.ndarray | None, still: np.ndarray,
                        ws: _Workspace) -> np.ndarray | None:
        """Moves that depend on what ran before (e.g. a transition cost): per step."""
        flat = np.concatenate((np.zeros(_FIRST_GENE, dtype=ids.dtype), ids.ravel()))
        steps = flat[ws.steps[:, 2:]]
        rows = self.rows if tables is None else self.rows[tables]
        body, world = step_moves(rows, steps, self.effects)
        body = np.array(body)
        body[still] = 0.0
        if world is not None:
            world = np.array(world)
            world[still] = 0.0
        return integrate_path(self.start, body, world, self.keep, (ws.q, ws.p)).h
