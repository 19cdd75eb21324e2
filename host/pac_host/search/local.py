"""Local search for turn cycles: climb single-gene changes until none improves, and iterated
local search (ILS), which kicks a local optimum (two genes changed, a repeating loop's net move
kept: :mod:`pac_host.search.kicks`) and climbs again, restarted when it stalls
(:class:`Chain`, which can stop and be carried on later).

Every evaluation goes through the coverage simulator (:func:`pac_host.coverage.simulate`); an
:class:`Objective` counts them, so a search can be given a budget in evaluations and stay
reproducible (a budget in seconds is not).
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from pac_host.coverage import DEFAULT_BUDGET, START_POSE, Scorer, fitness_of_search_score
from pac_host.coverage.noisy import NoisyScorer
from pac_host.coverage.placement import PlacementError
from pac_host.model.effects import Effect
from pac_host.model.step_noise import StepNoise
from pac_host.search.kicks import closing_kick, loop_table
from pac_host.search.neighbours import (
    canonical,
    gene_changes,
    neighbours,
    pair_neighbours,
    slots,
    value_indices,
)
from pac_host.search.recent import Recent
from pac_host.search.shapes import Source, source_key, starts, starts_by_source
from pac_host.search.shorten import CLIMBS, shorter_loops, shorter_windows

PAIRS = -1  # stands for the neighbourhood of paired repetition changes
# What the search scores are (Objective.fingerprint): a chain carried from a run whose scores
# ranked otherwise re-scores its point rather than compare scores of two kinds.
_SCORES = "search_score: fitness, reached sooner, fewer repeat visits"


# walks of a noisy batch scored between two looks at the deadline (about 0.1 s)
NOISY_CHUNK_WALKS = 1 << 17

# Batches scored with ``remember`` (a model's re-expressed library, which every chain of a
# punctuation scores on the same objective), by the objective's scores and the batch: the
# scores of the last few, so the next chain is charged the evaluations without walking them
# again (a noisy punctuation's eight chains spent almost a third of their time on this).
_REMEMBERED: Recent[tuple[np.ndarray, np.ndarray]] = Recent(16)


class Exhausted(Exception):
    """The objective's evaluation budget or deadline is spent."""


@dataclass
class Objective:
    """Scores turn cycles on one model for a search and counts evaluations against a budget.

    A call returns search scores (:func:`pac_host.coverage.search_score`: fitness, then the
    fitness reached sooner, then fewer repeat visits), which the searches compare;
    :meth:`fitness` reads the fitness from one. ``limit`` is the number of evaluations allowed
    (None: no limit); ``deadline`` a ``time.perf_counter()`` value after which no batch starts
    once one has been scored (None: none). With ``finish`` the limit stops no call and cuts no
    batch: :meth:`spent` says when it is reached, and a :class:`Chain` stops at the end of the
    move it is in (a deadline or ``cancelled`` still stops a call). The best turn cycle ever
    scored, its score (:meth:`Coverage.score`, as everything outside the searches ranks turn
    cycles) and when it was found (evaluations, seconds, fitness) are kept as a trace.

    With a ``placement`` error each turn cycle is walked from the placement's stencil of start
    poses around ``start_pose`` and the search scores are pooled over the walks
    (:mod:`pac_host.coverage.placement`): :meth:`fitness` is then the mean fitness of the walks,
    and an
    evaluation is one walk, so a turn cycle costs seven. With ``models`` (M, 32, 3), other
    tables the robot may be (the corrected model's posterior draws), each turn cycle is also
    walked on every one and pooled the same way (:class:`~pac_host.coverage.Scorer`): the
    search then prefers turn cycles whose rows the tests have pinned; the best turn cycle
    on the model alone among those scored is kept too (``best_alone``), the one the model is
    most hopeful about, worth a test.

    With ``step_noise`` each turn cycle is walked K times with the noise drawn from
    ``normals`` (K, budget, 3), the same for every turn cycle (common random numbers,
    :mod:`pac_host.coverage.noisy`), walk k from ``walk_starts[k]`` (None: ``start_pose``; a
    placement error is given as start poses drawn with it): the search scores rank the mean
    fitness of the walks (or their ``quantile``), which :meth:`fitness` reads, and a turn
    cycle costs K evaluations. The best of these scores favour the luck of K walks: the
    ``keep_finalists`` best turn cycles scored (distinct scores; each batch's best) are kept
    in :attr:`finalists` to be re-scored on fresh walks before one is believed.
    """

    rows: np.ndarray
    budget: int = DEFAULT_BUDGET
    effects: Sequence[Effect] = ()
    limit: int | None = None
    deadline: float | None = None
    start_pose: Sequence[float] = START_POSE
    cancelled: Callable[[], bool] | None = None
    placement: PlacementError | None = None
    models: np.ndarray | None = None
    finish: bool = False  # the limit waits for the end of a move (spent), never cuts one
    step_noise: StepNoise | None = None  # score over noisy walks (pac_host.coverage.noisy)
    normals: np.ndarray | None = None  # their standard normals (K, budget, 3)
    walk_starts: np.ndarray | None = None  # each noisy walk's start pose (K, 3)
    quantile: float | None = None  # rank the walks' fitness by this quantile (None: the mean)
    keep_finalists: int = 0
    finalists: list = field(default_factory=list)  # (search score, turn cycle), best first
    evaluations: int = 0  # walks simulated
    best: np.ndarray | None = None
    best_score: int | None = None  # the best's score (Coverage.score)
    best_search_score: int | None = None
    trace: list = field(default_factory=list)  # (evaluations, seconds, fitness) at each new best
    best_alone: np.ndarray | None = None  # with models: the best on the model alone
    best_alone_score: int | None = None
    t0: float = field(default_factory=time.perf_counter)
    # loops whose shorter windows have been scored on this objective (shorten tries each once)
    windows_tried: set = field(default_factory=set)

    def __post_init__(self) -> None:
        if self.step_noise is not None:
            if self.normals is None:
                raise ValueError("an objective with step noise needs its normals")
            self._scorer = NoisyScorer(
                self.rows, self.step_noise, self.normals, self.budget, self.effects,
                self.start_pose if self.walk_starts is None else self.walk_starts, self.quantile)
        else:
            poses = (self.start_pose if self.placement is None
                     else self.placement.stencil(self.start_pose))
            self._scorer = Scorer(self.rows, self.budget, self.effects, poses, self.models)
        self.starts = self._scorer.walks  # walks a turn cycle costs
        self._loop_table = None
        self._scores_key: str | None = None

    def loop_table(self) -> np.ndarray:
        """The model's gait cycles repeated 0..63 times
        (:func:`pac_host.search.kicks.loop_table`), made once: what a closing kick needs to
        know a loop's net move."""
        if self._loop_table is None:
            self._loop_table = loop_table(self.rows, self.effects)
        return self._loop_table

    def fingerprint(self) -> str:
        """A digest of what the scores depend on: the model, its effects, budget, start pose."""
        h = hashlib.sha256(np.ascontiguousarray(self.rows, dtype=np.float64).tobytes())
        h.update(repr((tuple(str(e) for e in self.effects), self.budget,
                       tuple(float(v) for v in self.start_pose), _SCORES)).encode())
        if self.placement is not None:
            h.update(repr(("placement", self.placement.to_text())).encode())
        if self.models is not None and len(self.models):
            h.update(np.ascontiguousarray(self.models, dtype=np.float64).tobytes())
        if self.step_noise is not None:
            h.update(repr(("step_noise", self.quantile)).encode())
            for a in (self.step_noise.sd, self.normals, self.walk_starts):
                if a is not None:
                    h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        return h.hexdigest()[:16]

    def fitness(self, search_score: int) -> int | float:
        """The coverage fitness inside one of this objective's search scores (with a
        placement error or models, the mean over the walks; with step noise, the mean or
        quantile of the noisy walks)."""
        if self.step_noise is not None:
            return self._scorer.fitness(search_score)
        total = int(fitness_of_search_score(search_score, self.budget, self.starts))
        return total if self.starts == 1 else total / self.starts

    def expired(self) -> bool:
        """Whether the deadline has passed or the search is cancelled. A deadline stops a search
        only once it has scored something: the first batch always runs, so a search given too
        little time still returns its start."""
        if self.cancelled is not None and self.cancelled():
            return True
        return (self.deadline is not None and self.best is not None
                and time.perf_counter() >= self.deadline)

    def remaining(self) -> int | None:
        return None if self.limit is None else self.limit - self.evaluations

    def spent(self) -> bool:
        """Whether the evaluation limit is reached (what a search with ``finish`` checks
        between moves)."""
        return self.limit is not None and self.evaluations >= self.limit

    def __call__(self, pop: np.ndarray, remember: bool = False) -> np.ndarray:
        """Search scores of turn cycles (N, 9, 2); raises :class:`Exhausted` when the budget
        is spent (a batch that would pass the evaluation limit is cut to it, so the count is
        exact; with ``finish`` neither: the caller stops between moves). ``remember``: a batch
        other objectives on the same model will score too; its scores are kept a while and
        taken from there, counted as evaluations all the same (:data:`_REMEMBERED`)."""
        if self.expired():
            raise Exhausted
        if (self.step_noise is not None and len(pop) * self.starts > NOISY_CHUNK_WALKS
                and (self.deadline is not None or self.cancelled is not None)):
            # a noisy batch costs K walks a turn cycle: a large one (a shorter loop's
            # proposals) is scored in parts, so a deadline stops it within a fraction of a second
            step = max(1, NOISY_CHUNK_WALKS // self.starts)
            return np.concatenate([self(pop[i:i + step], remember)
                                   for i in range(0, len(pop), step)])
        left = self.remaining()
        if left is not None and not self.finish:
            if left < self.starts:
                raise Exhausted
            pop = pop[: left // self.starts]
        keys, scores = self._both(pop) if remember else self._scorer.both(pop)
        self.evaluations += len(pop) * self.starts
        if self.models is not None and len(scores):
            j = int(np.argmax(scores))
            if self.best_alone_score is None or scores[j] > self.best_alone_score:
                self.best_alone, self.best_alone_score = pop[j].copy(), int(scores[j])
        if len(keys):
            i = int(np.argmax(keys))
            if self.keep_finalists:
                self._offer(pop[i], int(keys[i]))
            if self.best_search_score is None or keys[i] > self.best_search_score:
                self.best, self.best_search_score = pop[i].copy(), int(keys[i])
                self.best_score = int(scores[i])
                self.trace.append((self.evaluations, time.perf_counter() - self.t0,
                                   self.fitness(self.best_search_score)))
        return keys


    def _both(self, pop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The scorer's two scores of ``pop``, from :data:`_REMEMBERED` if an objective with
        the same scores has scored this batch (a turn cycle's scores do not depend on the
        batch it is in), else scored and kept there."""
        if self._scores_key is None:  # the fingerprint, with the effects' exact parameters
            effects = repr([(e.name, sorted(e.params.items())) for e in self.effects])
            self._scores_key = self.fingerprint() + effects
        genes = np.ascontiguousarray(pop, dtype=np.int64)
        key = (self._scores_key, genes.shape, hashlib.sha1(genes.tobytes()).hexdigest())
        found = _REMEMBERED.get(key, lambda: self._scorer.both(pop))
        return found[0].copy(), found[1].copy()

    def _offer(self, genes: np.ndarray, key: int) -> None:
        """Keep ``genes`` among the finalists if its search score is among the best kept
        (one turn cycle a score: equal scores are almost always the same walks)."""
        kept = self.finalists
        if len(kept) >= self.keep_finalists and key <= kept[-1][0]:
            return
        if any(k == key for k, _ in kept):
            return
        kept.append((key, genes.copy()))
        kept.sort(key=lambda e: -e[0])
        del kept[self.keep_finalists:]


def climb(x: np.ndarray, score: int, objective: Objective,
          rng: np.random.Generator | None = None,
          sample: float = 1.0) -> tuple[np.ndarray, int]:
    """Local search over single-gene changes until none scores higher.

    Without ``rng``: best improvement over the whole neighbourhood at each move. With it:
    the genes are visited in a random order, a gene's changes evaluated in one batch and the
    best taken as soon as it improves, the cheap changes (the gene's id or repetitions alone)
    before any change of the gene, and paired repetition changes last. With ``sample`` < 1
    (and ``rng``) each look at a gene's any-change neighbourhood (2,016 changes) scores a fresh
    random share of it, so the climb ends at a point no cheap, paired or sampled change
    improves: a cheaper, approximate local optimum (:data:`SAMPLE`). ``score`` and the score
    returned with the local optimum (canonical) are the objective's search scores."""
    if not 0 < sample <= 1:
        raise ValueError(f"sample must be in (0, 1], got {sample}")
    budget = objective.budget
    x = canonical(x, budget)
    if rng is None:
        while True:
            n = neighbours(x, budget)
            s = objective(n)
            i = int(np.argmax(s))
            if s[i] <= score:
                return x, score
            x, score = canonical(n[i], budget), int(s[i])
    # tiers of neighbourhoods, cheapest first: a gene's id or repetitions alone, any change
    # of one gene, paired repetition changes; an improvement anywhere restarts at the first
    # a move that improved is looked at again only once nothing else improves: its best
    # change was just taken
    tried: set[tuple[int, int]] = set()
    last = None
    changeable = [int(j) for j in slots(x, budget)]  # the slots worth changing, kept with x
    while True:
        move = None
        for tier in range(3):
            where = [PAIRS] if tier == 2 else changeable
            todo = [j for j in where if (tier, j) not in tried]
            if todo:
                move = tier, todo[rng.integers(len(todo))]
                break
        if move is None:
            if last is None or (last[1] != PAIRS and last[1] not in changeable):
                return x, score
            move, last = last, None
        tier, j = move
        if tier == 2:
            n = pair_neighbours(x, budget)
        elif tier == 1 and sample < 1:
            idx = value_indices(x[j])
            idx = idx[np.sort(rng.choice(len(idx), size=max(1, int(len(idx) * sample)),
                                         replace=False))]
            n = gene_changes(x, j, idx)
        else:
            n = neighbours(x, budget, only=j, small=tier == 0)
        s = objective(n)
        i = int(np.argmax(s)) if len(s) else 0
        if len(s) and s[i] > score:
            x, score = canonical(n[i], budget), int(s[i])
            changeable = [int(j) for j in slots(x, budget)]
            tried, last = {move}, move
        else:
            tried.add(move)


# The share of a gene's any-change neighbourhood a search's climb scores each time it looks
# (:func:`climb`). Measured (3 million evaluations a run, five tables, seeds 0-11): mean final
# fitness 30.8 with the whole neighbourhood, 32.1 with a quarter, 32.6 with a tenth. A climb
# then costs a fraction of the evaluations, so a chain makes several times the kicks; the
# changes a look skips are drawn afresh at the next look.
SAMPLE = 0.1


def shorten(x: np.ndarray, score: int, objective: Objective, rng: np.random.Generator,
            sample: float = SAMPLE, climbs: int = CLIMBS,
            windows: bool = True) -> tuple[np.ndarray, int] | None:
    """A local optimum past ``x`` (search score ``score``) reached through a shorter loop of the
    same sweep: two genes re-set (:func:`pac_host.search.shorten.shorter_loops`), then, if
    none of those climbs higher and ``windows``, four consecutive genes
    (:func:`pac_host.search.shorten.shorter_windows`, once per loop and objective: its
    proposals take about a second to list). Each kind's proposals are scored and the best
    ``climbs`` climbed in turn until one ends higher than ``score``; None if none does (or
    the loop does not repeat)."""
    table, budget = objective.loop_table(), objective.budget
    # listing the proposals takes up to seconds: it stops at the objective's deadline, and
    # scoring what was listed then ends the search
    found = _climb_best(shorter_loops(x, table, budget, expired=objective.expired), score,
                        objective, rng, sample, climbs)
    if found is not None or not windows:
        return found
    key = canonical(x, budget).tobytes()
    if key in objective.windows_tried:
        return None
    objective.windows_tried.add(key)
    return _climb_best(shorter_windows(x, table, budget, expired=objective.expired), score,
                       objective, rng, sample, climbs)


def _climb_best(proposals: np.ndarray, score: int, objective: Objective,
                rng: np.random.Generator, sample: float,
                climbs: int) -> tuple[np.ndarray, int] | None:
    """Of ``proposals`` scored, the first of the best ``climbs`` whose climb ends above
    ``score``, climbed; None if none does."""
    if not len(proposals):
        return None
    scores = objective(proposals)
    for i in np.argsort(-scores, kind="stable")[:climbs]:
        y, s = climb(proposals[i], int(scores[i]), objective, rng, sample)
        if s > score:
            return y, s
    return None


RESTART_POPULATION, RESTART_GENERATIONS = 64, 150  # the CGA run that starts each restart
# Start k's CGA population has its random repetitions divided by LOOP_DIVISORS[k % len]. A loop
# much shorter than the budget repeats, a periodic sweep; a long one is cut in its first pass,
# an open sweep. Their best turn cycles differ, and a CGA from random turn cycles (32
# repetitions a gene on average, a 288-cycle loop) almost always ends among the long ones.
# Measured: on the shifted table, 8 of 10 seeds at 34 or better in 20 s with (1, 4) against 4
# of 10 with (1,).
LOOP_DIVISORS = (1, 4)


@dataclass
class Chain:
    """Iterated local search with restarts that can stop when its objective's budget runs out
    and be carried on later, on the same model or a changed one (anytime PAL's search between
    punctuations). It keeps its current local optimum ``x`` (None: start from a restart) and the
    kicks ``stale`` since the score last rose; after ``patience`` such kicks it restarts: from
    the best start the library of sweeps has given (:meth:`run`), climbed afresh with other
    kicks, or without a library from the best of a fresh short CGA run (the CGA finds good
    regions cheaply; the local search then gets much further from there than the CGA does).
    The best ever scored is the objective's.

    >>> from pac_host.model import shifted_table
    >>> objective = Objective(shifted_table().rows, limit=20_000)
    >>> chain = Chain()
    >>> chain.run(objective, np.random.default_rng(0), patience=50)
    >>> objective.evaluations, objective.fitness(objective.best_search_score) > 10
    (20000, True)
    """

    x: np.ndarray | None = None
    stale: int = 0
    score: int | None = None  # x's search score on the model it was last climbed on, and the model
    model: str | None = None
    starts: int = 0  # starting points so far, a given one included (picks the loop divisor)
    shaped: str | None = None  # the model the shapes were last re-expressed on
    # the starts the shapes gave on that model and not yet taken, (turn cycle, search score,
    # source key) best first, one a source: the next is taken when it starts higher than the
    # origin (or there is none) at a restart, or beats the chain's point carried to that model
    queue: list = field(default_factory=list)
    # the sources started from so far, on any model (shapes.source_key): a changed model
    # queues only the others, so a run's restarts go through the whole library once instead
    # of climbing the same best source again after every punctuation; the taken ones' best
    # start on the new model may still replace the origin
    taken: list = field(default_factory=list)
    # the best start the sources have given, (turn cycle, search score, the model it was last
    # scored on): a restart climbs it again, with other kicks, re-scored on a changed model,
    # unless a source, taken or not, starts higher there
    origin: tuple | None = None
    # evaluations a run with a finishing objective spent past its limit, to be taken from the
    # next budget (pac_host.search.anytime.advance)
    overrun: int = 0

    def run(self, objective: Objective, rng: np.random.Generator, patience: int,
            kick_genes: int = 2, sample: float = SAMPLE,
            shapes: Sequence[Source] = (), length_cost: float = 0.0,
            shorten_after: int = 0, windows: bool = True,
            carried: Sequence[Source] = ()) -> None:
        """Search until the objective's budget or deadline is spent. A carried-on chain first
        re-scores and climbs its local optimum if the objective's model has changed. With
        ``shapes`` (sweeps and the tables they were found on, :mod:`pac_host.search.shapes`),
        the first start on a model is the best of them re-expressed on it, if that scores
        higher than the chain's own point, and each restart climbs the best start so far again
        (:attr:`origin`, re-scored on a changed model), unless a source not yet taken starts
        higher: climbs from one start end in different basins, and the best start's are the
        likeliest to end high (measured with one chain of a PAL run's 10.4 million
        evaluations, seeds 0-15: asymmetric 41.6 against 40.6 when restarts took the next
        source's start, outside_library 40.75 against 39.5; docs/explanation/learning.md). Every
        source
        is re-expressed on each model; one once started from (:attr:`taken`) is not queued
        again, but its start becomes the origin if it beats it (:meth:`_reshape`).
        ``length_cost``: the closing kicks' (:func:`pac_host.search.kicks.closing_kick`).
        ``shorten_after``: after this many kicks in a row without a higher score the chain
        tries shorter loops of its sweep (:func:`shorten`) and goes on from the first that
        climbs higher; 0: never. ``windows``: whether those include re-set windows of four
        genes. ``carried``: turn cycles found on an earlier model (as sources): on a changed
        model the best of their starts replaces the chain's point if it starts higher, but
        they are neither queued nor taken, so they never become the :attr:`origin` restarts
        climb. Taken as sources, a chain's own find was the best start on every later model
        and each restart climbed it again: eight chains of a PAL run on the exact noisy_rows
        table stayed on the 50s they had found (9 of 30 runs), where a fresh search of the
        same evaluations from the library ends at 53-54 (docs/explanation/learning.md, "Restarts
        from
        the library")."""
        model = objective.fingerprint()
        try:
            while True:
                self._stop_if_spent(objective)
                # re-expressed once per model, where a start is to be chosen
                if shapes and self.shaped != model and (self.x is None or self.model != model):
                    self._reshape(objective, shapes, model)
                queued = bool(self.queue) and self.shaped == model
                if self.x is None:
                    x, score = self._restart(objective, rng, model, queued)
                    self.starts += 1
                    self.x, self.stale, self.model = x, 0, None  # kept if the climb is cut
                elif self.model == model:
                    x, score = self.x, self.score
                else:
                    x, score = self.x, int(objective(self.x[None])[0])
                    if queued and self.queue[0][1] > score:
                        (x, score), self.stale = self._take(model), 0
                        self.x = x
                    found = starts(objective, carried) if carried else []
                    if found and found[0][1] > score:
                        (x, score), self.stale = found[0], 0
                        self.x = x
                if self.model != model:
                    x, score = climb(x, score, objective, rng, sample)
                    self.x, self.score, self.model = x, score, model
                while self.stale < patience:
                    self._stop_if_spent(objective)
                    y = closing_kick(x, rng, kick_genes, objective.budget,
                                     objective.loop_table(), length_cost=length_cost)
                    y, s = climb(y, int(objective(y[None])[0]), objective, rng, sample)
                    self.stale = 0 if s > score else self.stale + 1
                    if objective.fitness(s) >= objective.fitness(score):  # plateaus crossed
                        x, score = y, s
                        self.x, self.score = x, score
                    if shorten_after and self.stale == min(shorten_after, patience):
                        found = shorten(x, score, objective, rng, sample, windows=windows)
                        if found is not None:
                            x, score = found
                            self.x, self.score, self.stale = x, score, 0
                self.x, self.model = None, None
        except Exhausted:
            pass

    @staticmethod
    def _stop_if_spent(objective: Objective) -> None:
        """Between moves: stop once a finishing objective's limit is reached (a move is a
        restart's climb or a kick's, with the shorter loops it may try)."""
        if objective.finish and objective.spent():
            raise Exhausted

    def _reshape(self, objective: Objective, shapes: Sequence[Source], model: str) -> None:
        """Re-express every source on ``model``: the ones not yet taken queue up; the best
        start of the taken ones becomes the origin if it beats the origin re-scored there.
        Re-expressing only the untaken sources left the early-taken ones expressed on the
        early, wrong models for the rest of a run: noisy_rows runs that ended short had an
        exact model where used, and a fresh search of it found more (30 seeds: 25/30 at 95%
        of the best known after 25 punctuations, 27/30 with this; docs/explanation/learning.md)."""
        keys = [source_key(src) for src in shapes]
        every = starts_by_source(objective, list(shapes))
        self.queue = [(x, score, keys[o]) for x, score, o in every if keys[o] not in self.taken]
        again = [(x, score) for x, score, o in every if keys[o] in self.taken]
        if again and self.origin is not None:
            self._origin_on(objective, model)
            if again[0][1] > self.origin[1]:
                self.origin = (again[0][0].copy(), again[0][1], model)
        self.shaped = model

    def _restart(self, objective: Objective, rng: np.random.Generator, model: str,
                 queued: bool) -> tuple[np.ndarray, int]:
        """Where a restart starts: the origin (re-scored on a changed model) unless a source
        not yet taken starts higher, else the queue's next start, else a short CGA run."""
        if self.origin is not None:
            self._origin_on(objective, model)
            if not (queued and self.queue[0][1] > self.origin[1]):
                return self.origin[0].copy(), self.origin[1]
        if queued:
            return self._take(model)
        return cga_start(objective, rng, divisor=LOOP_DIVISORS[self.starts % len(LOOP_DIVISORS)])

    def _origin_on(self, objective: Objective, model: str) -> None:
        """The origin (the best start so far) re-scored on ``model`` if it was scored on
        another."""
        if self.origin[2] != model:
            genes = self.origin[0]
            self.origin = (genes, int(objective(genes[None])[0]), model)

    def _take(self, model: str) -> tuple[np.ndarray, int]:
        """The queue's next start, its source marked as taken; the origin of later restarts
        if it is the first start on ``model`` or beats the origin there."""
        x, score, key = self.queue.pop(0)
        if key is not None:
            self.taken.append(key)
        if self.origin is None or self.origin[2] != model or score > self.origin[1]:
            self.origin = (x.copy(), score, model)
        return x, score

    def to_json(self) -> dict:
        return {"x": None if self.x is None else self.x.tolist(), "stale": self.stale,
                "score": self.score, "model": self.model, "starts": self.starts,
                "shaped": self.shaped,
                "queue": [[g.tolist(), s, k] for g, s, k in self.queue],
                "taken": list(self.taken),
                "origin": None if self.origin is None else [
                    self.origin[0].tolist(), self.origin[1], self.origin[2]],
                "overrun": self.overrun}

    @classmethod
    def from_json(cls, doc: dict) -> Chain:
        x, score, model = doc.get("x"), doc.get("score"), doc.get("model")
        return cls(None if x is None else np.array(x, dtype=np.int64), int(doc.get("stale", 0)),
                   None if score is None else int(score), None if model is None else str(model),
                   int(doc.get("starts", 0)),
                   None if doc.get("shaped") is None else str(doc["shaped"]),
                   [_queued(*q) for q in doc.get("queue") or []],
                   [str(k) for k in doc.get("taken") or []],
                   None if doc.get("origin") is None else _origin(*doc["origin"]),
                   int(doc.get("overrun", 0)))


def _origin(genes, score, model) -> tuple[np.ndarray, int, str]:
    """A chain's origin from its JSON (one saved before origins has none)."""
    return np.array(genes, dtype=np.int64), int(score), str(model)


def _queued(genes, score, key=None) -> tuple[np.ndarray, int, str | None]:
    """A queue entry of a chain's JSON (one saved before sources were remembered has no key)."""
    return np.array(genes, dtype=np.int64), int(score), None if key is None else str(key)


def restarts(objective: Objective, rng: np.random.Generator, patience: int,
             kick_genes: int = 2, start: np.ndarray | None = None,
             sample: float = SAMPLE, shapes: Sequence[Source] = (),
             length_cost: float = 0.0, shorten_after: int = 0,
             windows: bool = True) -> None:
    """Iterated local search from ``start`` (or the best of ``shapes`` re-expressed on the
    model, or of a short CGA run), restarted whenever it stalls for ``patience`` kicks, until
    the budget runs out (a :class:`Chain` run to the end); the best is ``objective.best``."""
    Chain(start, starts=int(start is not None)).run(objective, rng, patience, kick_genes,
                                                    sample, shapes, length_cost,
                                                    shorten_after, windows)


def cga_start(objective: Objective, rng: np.random.Generator,
              divisor: int = 1) -> tuple[np.ndarray, int]:
    """The best turn cycle of a short CGA run from a random population, scored through the
    objective (so its evaluations count); the population's repetitions are divided by
    ``divisor``, to start among shorter, repeating loops (:data:`LOOP_DIVISORS`)."""
    from pac_host.search import cga

    cfg = cga.CGAConfig(population=RESTART_POPULATION, budget=objective.budget)
    pop = cga.random_population(rng, cfg.population)
    pop[..., 1] //= divisor
    fit = objective(pop)
    for _ in range(RESTART_GENERATIONS):
        pop = cga.step(pop, fit, rng, cfg)
        fit = objective(pop)
    i = int(np.argmax(fit))
    return pop[i], int(fit[i])
