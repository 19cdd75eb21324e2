"""The anytime search of a PAL punctuation (``cfg.search`` other than "cga"): searches the
model while the robot walks the tests, then spends its budget on the model the tests have
corrected (:class:`_AnytimeSearch`), and ranks turn cycles on a model as that search compares
them (:func:`_ranking`).

With ``search_noise`` and the robot's step noise estimated clearly above zero, the search ranks
turn cycles by their mean fitness over :data:`SEARCH_WALKS` noisy walks of the model with that
noise, common random numbers drawn each punctuation from a seed the search's own generator
gives (kept with the carried search as ``walks_seed``, so the ranking between punctuations and
a resumed run walk the same normals: :func:`search_walks`)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence

import numpy as np

from pac_host.coverage import START_POSE, Scorer, format_turn_cycle
from pac_host.learning.config import PALConfig
from pac_host.learning.state import PALState
from pac_host.model.effects import Effect
from pac_host.model.step_noise import StepNoise
from pac_host.search import cga, shapes
from pac_host.search.optimize import FRESH_WALKS, WALKS_DEFAULT

# noisy walks of the model a turn cycle is scored over when the search knows the robot's step
# noise: optimize's (measured there: 32 walks found higher expected sweeps than 64 in one time)
SEARCH_WALKS = WALKS_DEFAULT
# fresh noisy walks of the model the chains' finds are ranked on (:func:`fresh_means`), and the
# seed stream they are drawn from beside the search walks' seed
RANK_WALKS, RANK_STREAM = FRESH_WALKS, 1


class _AnytimeSearch:
    """The search of one punctuation: while the robot walks the tests (in a worker thread, on a
    real robot) it searches without a budget on the model the tests were chosen on; once the
    tests have corrected the model, it spends its budget of evaluations on the corrected one,
    so the next tests come from a search of the freshest model."""

    def __init__(self, state: PALState, rng: np.random.Generator, cfg: PALConfig) -> None:
        self.state, self.rng, self.cfg = state, rng, cfg
        self.pop = state.cga_pop
        self.chain = state.search
        # the step noise the search walks the model with (None: one noise-free walk)
        self.noise = state.step_noise if cfg.search_noise else None
        self.walking_evaluations: int | None = None
        self.walking_best = -1
        self.record: dict = {}
        self.cancelled = False
        self.walking = threading.Event()
        self.walking.set()

    def cancel(self) -> None:
        """Stop early (the robot's tests failed): the punctuation will be redone."""
        self.cancelled = True

    def walked(self) -> None:
        """The robot has walked the tests: the search while walking stops."""
        self.walking.clear()

    def while_walking(self) -> None:
        """Search the current model until the robot has walked the tests (the worker's job)."""
        from pac_host.search import anytime
        from pac_host.search.local import Chain

        carried = None if self.chain is None else Chain.from_json(self.chain)
        walks = search_walks(self.noise, self._walks_seed(self.noise), self.cfg)
        self.pop, rec, chain = anytime.advance(
            self.state.models[0], self.pop, None, self.rng, self.cfg.budget,
            self.state.model_effects, self.cfg.search,
            cancelled=lambda: self.cancelled or not self.walking.is_set(), chain=carried,
            placement=self.cfg.placement_error(),
            models=_pooled_models(self.state.models, self.cfg),
            length_cost=self.cfg.kick_length_cost, shorten_after=self.cfg.shorten_after,
            windows=self.cfg.shorten_windows, **walks)
        self.chain = chain.to_json()
        self.walking_evaluations = rec["evaluations"]
        self.walking_best = rec.get("best_score", -1)

    def _walks_seed(self, noise: StepNoise | None) -> int | None:
        """A fresh seed for the noisy walks from the search's generator (None without noise:
        no draw, so a noise-free search's stream is today's)."""
        return None if noise is None else int(self.rng.integers(2**63))

    def on_corrected(self, models: np.ndarray, effects: Sequence[Effect],
                     operational: np.ndarray, noise: StepNoise | None = None) -> None:
        """Spend the budget on the corrected model ``models[0]``, from the population ranked
        on it, its sources the library and the search's best and the ``operational`` turn
        cycle from the model before (one the same as another adds no start:
        :func:`pac_host.search.shapes.starts`); with ``cfg.search_chains`` above one, the
        other chains each from its own point (:meth:`_other_chains`); with ``cfg.explore``, a
        share of it on ``models[1]`` (a draw from the posterior), from the best found. With
        ``noise`` (the robot's step noise, clearly estimated) and ``cfg.search_noise``, every
        turn cycle is scored over the same fresh noisy walks (:func:`search_walks`)."""
        from pac_host.search import anytime
        from pac_host.search.local import Chain

        library = shapes.load(self.cfg.shapes)

        noise = noise if self.cfg.search_noise else None

        def sources(*found: np.ndarray) -> tuple[list, list]:
            """The library's sources of starts (its robust sweeps too for a noisy search), and
            the turn cycles found on the model before (as sources: the library's too unless
            ``cfg.library_restarts``); none without a library."""
            if not library.shapes:
                return [], []
            carried = [shapes.carried(x, self.state.models[0], self.state.model_effects)
                       for x in found]
            own = library.sources(noisy=noise is not None)
            if self.cfg.library_restarts:
                return own, carried
            return own + carried, []

        seed = self._walks_seed(noise)
        walks = search_walks(noise, seed, self.cfg)
        rank, _ = _ranking(models, self.pop, self.cfg, effects, noise, seed)
        pop = self.pop[np.argsort(-rank, kind="stable")]
        carried = None if self.chain is None else Chain.from_json(self.chain)
        others = [Chain.from_json(doc) for doc in (self.chain or {}).get("others", [])]
        budget = self.cfg.search_evaluations * (self.cfg.noisy_search_scale if walks else 1)
        explore = round(budget * self.cfg.explore) if len(models) > 1 else 0

        def search(rng: np.random.Generator, chain: Chain | None, found: Sequence[np.ndarray]):
            """One chain's search of the corrected model, from its chain, the library and
            ``found`` (every chain's the same way)."""
            library_sources, carried = sources(*found)
            return anytime.advance(models[0], pop, budget - explore, rng, self.cfg.budget,
                                   effects, self.cfg.search, chain=chain,
                                   placement=self.cfg.placement_error(),
                                   models=_pooled_models(models, self.cfg),
                                   shapes=library_sources,
                                   length_cost=self.cfg.kick_length_cost,
                                   shorten_after=self.cfg.shorten_after,
                                   windows=self.cfg.shorten_windows, carried=carried,
                                   finish=self.cfg.finish_moves, **walks)

        self.pop, rec, chain = search(self.rng, carried, (self.pop[0], operational))
        self.chain = chain.to_json()
        self.record = {"method": self.cfg.search, **rec}
        if seed is not None:  # what the ranking between punctuations walks again
            self.chain["walks_seed"] = seed
            self.record.update(step_noise=noise.to_json(), walks=SEARCH_WALKS)
        if self.cfg.search_chains > 1:
            self._other_chains(search, others, models[0], effects, noise, seed)
        if explore > 0:
            found, done, _ = anytime.advance(models[1], self.pop[:1], explore, self.rng,
                                             self.cfg.budget, effects, self.cfg.search,
                                             placement=self.cfg.placement_error(),
                                             length_cost=self.cfg.kick_length_cost,
                                             shorten_after=self.cfg.shorten_after,
                                             windows=self.cfg.shorten_windows, **walks)
            self.chain["explore"] = found[0].tolist()
            self.record.update(explore=format_turn_cycle(found[0]),
                               explore_evaluations=done["evaluations"])
        if self.walking_evaluations is not None:
            self.record["evaluations_while_walking"] = self.walking_evaluations
            self.record["best_score_while_walking"] = self.walking_best

    def _other_chains(self, search: Callable, others: list, rows: np.ndarray,
                      effects: Sequence[Effect], noise: StepNoise | None,
                      walks_seed: int | None) -> None:
        """Chains 1.. of ``cfg.search_chains``, each run by ``search`` as chain 0 was, but
        from its own carried point in ``others`` (the population's best on the first
        punctuation) with that point as its source, not the population's best or the
        operational turn cycle (both the best chain's finds), on a generator seeded from the
        run's; the best any chain found goes to the population's front, so it is tested (a tie
        keeps the earlier chain's). Given the best chain's find, every chain started there
        whenever it beat the chain's own point, and the chains ended most punctuations on one
        point: eight tries from one place, not eight searches (outside_library, 30 seeds: 26
        ended at 95% of the best known or more, against 13; docs/explanation/learning.md,
        "Chains kept apart"). With step ``noise`` the chains' finds are ranked by their mean
        over :data:`RANK_WALKS` fresh noisy walks of the model (:func:`fresh_means`), not by
        the searches' own walks: the highest of eight means over the same 32 walks is the
        luckiest as often as the best."""
        from pac_host.search.anytime import to_front

        seeds = self.rng.integers(2**63, size=self.cfg.search_chains - 1)
        found = [(self.record.get("best_score", -1), self.pop[0])]
        docs = []
        for j, seed in enumerate(seeds):
            mine = others[j] if j < len(others) else None
            out, rec, chain = search(np.random.default_rng(int(seed)), mine, _own_point(mine))
            docs.append(chain.to_json())
            found.append((rec.get("best_score", -1), out[0]))
        scores = [int(score) for score, _ in found]
        best = scores.index(max(scores))
        if noise is not None and walks_seed is not None:
            means = fresh_means(rows, np.stack([x for _, x in found]), noise, walks_seed,
                                self.cfg, effects)
            best = int(np.argmax(means))
            self.record["chain_fresh_means"] = [round(float(m), 3) for m in means]
        self.pop = to_front(self.pop, found[best][1])[: len(self.pop)]
        self.chain["others"] = docs
        self.record.update(chain_scores=scores, best_chain=best)


def _own_point(chain) -> tuple[np.ndarray, ...]:
    """A carried chain's point (its local optimum, or between climbs the best start it
    restarts from) as its own source of starts on the next model; none for a new chain."""
    if chain is None:
        return ()
    if chain.x is not None:
        return (chain.x,)
    return () if chain.origin is None else (chain.origin[0],)


def _pooled_models(models: np.ndarray, cfg: PALConfig) -> np.ndarray | None:
    """The tables besides the model (``models[0]``) an anytime search pools its scores over."""
    return models[1:cfg.search_models] if cfg.search_models > 1 else None


def search_walks(noise: StepNoise | None, seed: int | None, cfg: PALConfig) -> dict:
    """The noisy walks a search with step ``noise`` scores every turn cycle over, as
    :func:`pac_host.search.anytime.advance`'s arguments: :data:`SEARCH_WALKS` walks' normals
    and, with a placement error, their start poses, all from ``seed``; {} without noise."""
    if noise is None or seed is None:
        return {}
    from pac_host.coverage.noisy import draw_normals

    rng = np.random.default_rng(seed)
    normals = draw_normals(rng, SEARCH_WALKS, cfg.budget)
    error = cfg.placement_error()
    return {"step_noise": noise, "normals": normals,
            "walk_starts": None if error is None else error.draw(SEARCH_WALKS, rng)}


def fresh_means(rows: np.ndarray, genes: np.ndarray, noise: StepNoise, walks_seed: int,
                cfg: PALConfig, effects: Sequence[Effect] = ()) -> np.ndarray:
    """The mean fitness of turn cycles ``genes`` (P, 9, 2) over :data:`RANK_WALKS` noisy walks
    of ``rows`` apart from the search's (drawn from ``walks_seed`` with a stream of their own,
    so a resumed run walks them again), each from a start drawn with the placement error."""
    from pac_host.coverage.noisy import NoisyWalks, draw_normals

    rng = np.random.default_rng([walks_seed, RANK_STREAM])
    normals = draw_normals(rng, RANK_WALKS, cfg.budget)
    error = cfg.placement_error()
    starts = START_POSE if error is None else error.draw(RANK_WALKS, rng)
    return NoisyWalks(rows, noise, normals, cfg.budget, effects, starts).figures(genes)[2].mean(
        axis=1)


def carried_walks(state: PALState, cfg: PALConfig) -> tuple[StepNoise | None, int | None]:
    """The step noise and walks' seed the state's carried search last ranked with (None,
    None: a noise-free search)."""
    seed = (state.search or {}).get("walks_seed")
    if not cfg.search_noise or state.step_noise is None or seed is None:
        return None, None
    return state.step_noise, int(seed)


def _ranking(models: np.ndarray, pop: np.ndarray, cfg: PALConfig, effects: Sequence[Effect],
             noise: StepNoise | None = None, walks_seed: int | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """What an anytime search ranks turn cycles (P, 9, 2) by on the model ``models[0]`` (their
    coverage scores from the start, or with a placement error or pooled models their search
    scores pooled over the walks, or with step ``noise`` their mean fitness over
    :data:`RANK_WALKS` fresh walks of ``walks_seed`` (:func:`fresh_means`), as the chains'
    finds are ranked), and their coverage scores on the model from the start."""
    if noise is not None and walks_seed is not None:
        rank = fresh_means(models[0], pop, noise, walks_seed, cfg, effects)
        return rank, cga.fitness(models[0], pop, cfg.budget, effects)
    error, pooled = cfg.placement_error(), _pooled_models(models, cfg)
    if error is None and pooled is None:
        fit = cga.fitness(models[0], pop, cfg.budget, effects)
        return fit, fit
    poses = START_POSE if error is None else error.stencil()
    return Scorer(models[0], cfg.budget, effects, poses, pooled).both(pop)
