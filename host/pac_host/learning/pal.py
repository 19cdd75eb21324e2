"""Punctuated anytime learning (DESIGN.md 2.5): the CGA learns on the model while the model GA
corrects the model from periodic tests on the robot.

Every punctuation, the CGA's best turn cycle and two perturbations of it run on the robot (real
or simulated) and on every model; the model GA evolves the models towards the robot's results;
its best model becomes the CGA's model; the robot's operational turn cycle is replaced only when
the CGA's best does better on the robot.

The robot is anything with ``run_tests(tests) -> list[TestResult]`` (:class:`Robot`); the
simulated actual robot of the paper is :class:`SimulatedRobot`.

>>> import numpy as np
>>> from pac_host.model import measured_table, shifted_table
>>> robot = SimulatedRobot(shifted_table())
>>> state = initial_state(measured_table(), np.random.default_rng(0), PALConfig(cga_population=16))
>>> state, rec = punctuate(state, robot, np.random.default_rng(1), PALConfig(cga_population=16))
>>> len(rec["tests"]), rec["generation"]
(3, 0)
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from pac_host import limits
from pac_host.coverage import (
    DEFAULT_BUDGET,
    MAX_REPS,
    START_POSE,
    Coverage,
    Scorer,
    coverage_score,
    fitness_of_score,
    format_turn_cycle,
    placement,
    simulate,
)
from pac_host.errors import InputError
from pac_host.learning import model_fit, model_ga, test_selection
from pac_host.learning.robot_time import seconds_of_tests
from pac_host.model.effects import Effect
from pac_host.model.table import GaitTable
from pac_host.search import cga, shapes
from pac_host.search.kicks import check_length_cost, loop_table
from pac_host.search.shorten import check_shorten_after

CORRECTIONS = ("ga", "fit")
OPERATIONAL = ("best", "tested")


@dataclass(frozen=True)
class TestResult:
    """What the robot did on one tested turn cycle: coverage figures, and the path if observed."""

    blocks_covered: int
    blocks_covered_once: int
    fitness: int
    repeat_visits: int
    poses: np.ndarray | None = None

    @property
    def score(self) -> int:
        return int(coverage_score(self.fitness, self.repeat_visits))

    def figures(self) -> dict:
        return {
            "blocks_covered": self.blocks_covered,
            "blocks_covered_once": self.blocks_covered_once,
            "fitness": self.fitness,
            "repeat_visits": self.repeat_visits,
        }


class Robot(Protocol):
    """The robot side of PAL: runs each turn cycle from the start pose for the budget."""

    def run_tests(self, tests: np.ndarray) -> list[TestResult]: ...


def results_from_coverage(cov: Coverage) -> list[TestResult]:
    poses = cov.poses if cov.poses is not None else [None] * len(cov.fitness)
    return [
        TestResult(int(c), int(o), int(f), int(r), p)
        for c, o, f, r, p in zip(
            cov.blocks_covered, cov.blocks_covered_once, cov.fitness, cov.repeat_visits, poses,
            strict=True,
        )
    ]


@dataclass
class SimulatedRobot:
    """The paper's simulated actual robot: a true table (with its effects) in the simulator."""

    table: GaitTable
    budget: int = DEFAULT_BUDGET
    start_pose: Sequence[float] = START_POSE

    def run_tests(self, tests: np.ndarray) -> list[TestResult]:
        cov = simulate(self.table.rows, tests, self.budget, self.table.effects, self.start_pose,
                       keep_paths=True)
        return results_from_coverage(cov)


@dataclass(frozen=True)
class PALConfig:
    """Settings of the PAL loop (DESIGN.md 2.5 and the project's GA defaults)."""

    method: str = "partial"
    model_fitness: str = "coverage"  # the paper's six differences; "steps": observed paths
    generations: int = 1000  # CGA generations in all
    interval: int = 40  # CGA generations between punctuations
    model_generations: int = 0  # model GA generations per punctuation (the paper: 40)
    cga_population: int = 128
    model_population: int = 64
    budget: int = DEFAULT_BUDGET
    perturb_prob: float = 0.25
    perturb_reps: int = 50
    # Between punctuations: "cga", ``interval`` generations of the CGA after the model GA (the
    # paper); or "ils", anytime: ``search_evaluations`` coverage evaluations of iterated local
    # search on the model each punctuation's tests have just corrected (pac_host.search.anytime).
    search: str = "cga"
    search_evaluations: int = 0
    # With an anytime search and a worker (evolve): also search, on the model the tests were
    # chosen on, while the robot walks them. A real robot walks about 13 minutes a punctuation,
    # hundreds of millions of evaluations; the run is then no longer reproducible from its seed.
    search_while_walking: bool = False
    # The model correction: "ga", the model GA alone (the paper); "fit", the whole table fitted
    # to every observed step (effects of the library, then rows by evidence: model_fit), then
    # ``model_generations`` of the model GA on top (0: the fitted table alone).
    correction: str = "fit"
    structure: str = "effects"  # with "fit": "effects" or "none" (rows by evidence alone)
    # "paper": best + two perturbations; "informative" and "rows": pac_host.learning.test_selection
    tests: str = "rows"
    operational: str = "tested"  # "best": only the CGA's best may replace it (the paper)
    # With an anytime search: "POS_CM,HEAD_DEG", score turn cycles from a stencil of start poses
    # for a robot placed by hand with these standard deviations (pac_host.coverage.placement);
    # "none":
    # from the exact start alone
    placement: str = "none"
    # With an anytime search: score each turn cycle on this many of the corrected model's
    # population (the model, then draws from its posterior), pooled, so a turn cycle whose
    # rows the tests have not pinned scores lower; 1: on the model alone
    search_models: int = 1
    # With an anytime search: this many chains search each corrected model, each with the whole
    # budget and carried on from punctuation to punctuation, and the best any of them finds is
    # tested. Climbs from one start end in different basins and one chain stays in its basin
    # whatever its budget, so more chains, not a longer one, is what more host time buys
    # (docs/learning.md, "Eight search chains a punctuation"); 1: one chain, 8 in the default
    # profile. While the robot walks (search_while_walking) chain 0 alone searches
    search_chains: int = 1
    # With an anytime search: a library of good sweeps ("builtin", "none" or a pac-shapes/1
    # file), re-expressed on each new model as starting points (pac_host.search.shapes), with
    # the search's own best from the model before
    shapes: str = "none"
    # With an anytime search and a model population: this share of the budget searches
    # model 1 (with the "fit" correction a draw from the corrected model's posterior; with
    # "ga", e.g. a counts-only observer, the model GA's second best), from the search's best,
    # and the best found there takes the test after the best (Thompson sampling): a sweep over
    # rows no test has pinned gets tested when a plausible table favours it
    explore: float = 0.0
    # With an anytime search: cm of the closing kick's repair error that one gait cycle more of
    # the kicked loop weighs (pac_host.search.kicks.closing_kick), so the kicks prefer shorter
    # loops with the same net move; 0: the repair by closeness alone
    kick_length_cost: float = 0.0
    # With an anytime search: kicks in a row without progress after which a chain tries
    # shorter loops of its sweep, two genes re-set so the pass ends where it did
    # (pac_host.search.shorten); 0: never
    shorten_after: int = 0
    # whether those shorter loops include re-set windows of four consecutive genes
    # (pac_host.search.shorten.shorter_windows)
    shorten_windows: bool = False
    # With an anytime search and a library: whether the search's finds on the model before
    # only move a chain's point on the new model (True), or are sources like the library's,
    # so a chain's own find becomes the best start its restarts climb again (False, runs
    # saved before it)
    library_restarts: bool = False
    # With an anytime search: whether a chain ends the move it is in when its budget runs out
    # and pays what it spent past it from its next budget (True), or is cut at the budget
    # (False, runs saved before it), which lost every move costing about a budget
    # (pac_host.search.anytime.advance)
    finish_moves: bool = False
    # With the "fit" correction: whether the sequence and world effects' parameters are fitted
    # again with the rows on every run each punctuation (True), or kept as the structure
    # selection estimated them on its latest runs (False, runs saved before it), whose
    # transition off by 0.01 left a misfit that predicted 49 blocks where the robot covered 32
    # (pac_host.learning.model_fit.refine_effects)
    refine_effects: bool = False
    cga: cga.CGAConfig = field(default_factory=cga.CGAConfig)
    model: model_ga.ModelGAConfig = field(default_factory=model_ga.ModelGAConfig)

    def cga_config(self) -> cga.CGAConfig:
        return replace(self.cga, population=self.cga_population, budget=self.budget)

    def model_config(self) -> model_ga.ModelGAConfig:
        return replace(self.model, population=self.model_population, budget=self.budget)

    def check(self) -> None:
        """One clear error for a setting out of its choices."""
        for name, choices in (("correction", CORRECTIONS), ("structure", model_fit.STRUCTURES),
                              ("tests", test_selection.CHOICES), ("operational", OPERATIONAL),
                              ("method", model_ga.METHODS), ("model_fitness", model_ga.FITNESSES)):
            if getattr(self, name) not in choices:
                raise InputError(f"--{name.replace('_', '-')} takes {', '.join(choices)}, "
                                 f"got {getattr(self, name)!r}")
        if self.search not in ("cga", "ils"):
            raise InputError(f"search between punctuations must be cga or ils, got "
                             f"{self.search!r}")
        if self.search != "cga":
            limits.SEARCH_EVALUATIONS.check(self.search_evaluations, "--search-evaluations")
        limits.SEARCH_MODELS.check(self.search_models, "--search-models")
        if self.search_models > 1 and self.search == "cga":
            raise InputError("--search-models needs an anytime profile (the paper's CGA "
                             "scores on one model)")
        limits.CHAINS.check(self.search_chains, "--search-chains")
        if self.search_chains > 1 and self.search == "cga":
            raise InputError("--search-chains needs an anytime profile (the paper's CGA is "
                             "one population)")
        if self.search_models > self.model_population:
            raise InputError(f"--search-models {self.search_models} is more than the "
                             f"{self.model_population} models there are")
        if self.shapes != "none" and self.search == "cga":
            raise InputError("--shapes needs an anytime profile (the paper's CGA starts from "
                             "its own population)")
        shapes.load(self.shapes)  # one clear error for a bad library
        check_length_cost(self.kick_length_cost)
        if self.kick_length_cost and self.search == "cga":
            raise InputError("--kick-length-cost needs an anytime profile (the paper's CGA "
                             "makes no kicks)")
        check_shorten_after(self.shorten_after)
        if self.shorten_after and self.search == "cga":
            raise InputError("--shorten-after needs an anytime profile (the paper's CGA makes "
                             "no kicks)")
        if not 0.0 <= self.explore < 1.0:
            raise InputError(f"--explore must be a share in [0, 1), got {self.explore}")
        if self.explore > 0 and self.search == "cga":
            raise InputError("--explore needs an anytime profile (the paper's CGA searches one "
                             "model)")
        if self.placement_error() is not None and self.search == "cga":
            raise InputError("--placement-error needs an anytime profile (the paper's CGA "
                             "scores from the exact start)")

    def placement_error(self) -> placement.PlacementError | None:
        return placement.parse_placement(self.placement)


# The paper's method (DESIGN.md 2.5): PALConfig(**PAPER) runs it with today's exact results.
PAPER = {"correction": "ga", "tests": "paper", "operational": "best", "model_fitness": "coverage",
         "model_generations": 40}


def model_generations_for(correction: str, given: int | None) -> int:
    """Model GA generations per punctuation: as given, else the paper's 40 for its model GA
    and none on a fitted table (the GA on top was not measured to help: docs/learning.md)."""
    if given is not None:
        return given
    return PAPER["model_generations"] if correction == "ga" else 0


@dataclass
class PALState:
    """Everything a PAL run carries from one punctuation to the next (enough to resume)."""

    generation: int
    cga_pop: np.ndarray  # (P, 9, 2), best on the current model first
    models: np.ndarray  # (M, 32, 3), best first
    model_effects: tuple
    operational: np.ndarray  # (9, 2), the robot's current turn cycle
    operational_score: int | None  # its coverage score on the robot (None: not tested yet)
    operational_fitness: int | None
    base: GaitTable | None = None  # the starting model ("fit" corrects it from all evidence)
    observed: tuple = ()  # every observed test so far (model_fit.Observed), for "fit"
    search: dict | None = None  # the anytime search carried on (search.local.Chain.to_json())
    # the effects the "fit" correction last selected, and the observed runs it had then
    structure: tuple = ()
    structure_runs: int | None = None


def initial_state(
    model: GaitTable,
    rng: np.random.Generator,
    cfg: PALConfig = PALConfig(),
    cga_pop: np.ndarray | None = None,
) -> PALState:
    """Models perturbed from ``model``; the CGA population given (e.g. the final population of a
    long run on the model) or random, sorted best first on the model."""
    mcfg = cfg.model_config()
    models = model_ga.perturbed_population(model.rows, cfg.model_population, rng, mcfg.scale)
    if cga_pop is None:
        cga_pop = cga.random_population(rng, cfg.cga_population)
    library = shapes.load(cfg.shapes) if cfg.search != "cga" else shapes.Library(())
    if library.shapes:  # the library's best sweep on the model takes the last place
        found = shapes.proposals(library.sources(), loop_table(model.rows, model.effects),
                                 cfg.budget)
        best = found[int(np.argmax(cga.fitness(model.rows, found, cfg.budget, model.effects)))]
        cga_pop = np.concatenate([cga_pop[:-1], best[None]])
    fit = cga.fitness(model.rows, cga_pop, cfg.budget, model.effects)
    cga_pop = cga_pop[np.argsort(-fit, kind="stable")]
    return PALState(0, cga_pop, models, tuple(model.effects), cga_pop[0].copy(), None, None,
                    model)


def perturbations(best: np.ndarray, rng: np.random.Generator, cfg: PALConfig) -> np.ndarray:
    """The paper's two test perturbations of the best turn cycle: +-1 on each non-zero
    repetition count; and each gene, with probability 0.25, set to 50 repetitions."""
    a = best.copy()
    nz = a[:, 1] > 0
    a[nz, 1] = np.clip(a[nz, 1] + rng.choice([-1, 1], size=int(nz.sum())), 0, MAX_REPS)
    b = best.copy()
    b[rng.random(len(b)) < cfg.perturb_prob, 1] = cfg.perturb_reps
    return np.stack([a, b])


def model_error_fn(tests: np.ndarray, results: list[TestResult], cfg: PALConfig,
                   effects: Sequence = ()) -> model_ga.ErrorFn:
    """The model GA's score of disagreement with the robot on these tests (lower is better)."""
    if cfg.model_fitness == "coverage":
        observed = np.array([[r.blocks_covered, r.blocks_covered_once] for r in results])
        return lambda t: model_ga.model_fitness(t, tests, observed, cfg.budget, effects)
    if cfg.model_fitness == "steps":
        if any(r.poses is None for r in results):
            raise InputError("model fitness 'steps' needs the robot's observed paths; this "
                             "observer reports coverage counts only (use --model-fitness coverage)")
        return model_ga.step_error(tests, [r.poses for r in results], cfg.budget, effects)
    raise InputError(f"unknown model fitness {cfg.model_fitness!r}; use one of "
                     f"{', '.join(model_ga.FITNESSES)}")


def _number(v) -> int | float:
    v = v.item() if hasattr(v, "item") else v
    return int(v) if float(v).is_integer() else round(float(v), 6)


def punctuate(
    state: PALState, robot: Robot, rng: np.random.Generator, cfg: PALConfig = PALConfig(),
    concurrent: bool = False,
) -> tuple[PALState, dict]:
    """One punctuation: test on the robot, update the operational solution, evolve the models.

    With an anytime search (``cfg.search`` other than "cga") the turn-cycle search spends its
    budget on the model these tests have just corrected, so the next tests come from the
    freshest model; with ``concurrent`` and ``cfg.search_while_walking`` it also searches the
    current model in a worker thread while the robot walks the tests (the robot's link and
    observer keep the main thread), a search without a budget and so not reproducible. The
    search draws from its own generator, split off ``rng`` first. Returns the new state and a
    JSON-ready record of what happened.
    """
    tests = choose_tests(state, rng, cfg)
    model_rows = state.models[0]
    predicted = simulate(model_rows, tests, cfg.budget, state.model_effects)
    search = None
    if cfg.search != "cga":  # at the last punctuation too: a run carried on needs its result
        search = _AnytimeSearch(state, np.random.default_rng(rng.integers(2**63)), cfg)
    if search is not None and concurrent and cfg.search_while_walking:
        with ThreadPoolExecutor(1) as pool:
            job = pool.submit(search.while_walking)
            try:
                results = robot.run_tests(tests)
            except BaseException:
                search.cancel()
                raise
            finally:
                search.walked()
                job.result()
    else:  # in line there is no walking to search through
        results = robot.run_tests(tests)

    # the operational turn cycle: the best tested (or only the CGA's best, as in the paper),
    # replaced only when it does better on the robot
    k = int(np.argmax([r.score for r in results])) if cfg.operational == "tested" else 0
    replaced = state.operational_score is None or results[k].score > state.operational_score
    if replaced:
        operational, op_score, op_fit = tests[k].copy(), results[k].score, results[k].fitness
    else:
        operational = state.operational
        op_score, op_fit = state.operational_score, state.operational_fitness

    if cfg.correction == "fit":
        models, errors, model_effects, observed, fit_record, structure = _fit_correction(
            state, tests, results, rng, cfg)
        error_before = model_error_fn(tests, results, replace(cfg, model_fitness="steps"),
                                      state.model_effects)(state.models[:1])[0]
    else:
        error_fn = model_error_fn(tests, results, cfg, state.model_effects)
        error_before = error_fn(state.models[:1])[0]
        models, errors = model_ga.evolve(
            state.models, tests, None, cfg.model_generations, rng, cfg.method,
            cfg.model_config(), state.model_effects, error_fn,
        )
        model_effects, observed, fit_record = state.model_effects, state.observed, {}
        structure = (state.structure, state.structure_runs)
    record = {
        "generation": state.generation,
        "method": cfg.method,
        "tests": [format_turn_cycle(t) for t in tests],
        "observed": [r.figures() for r in results],
        "predicted": [
            {"blocks_covered": int(c), "blocks_covered_once": int(o), "fitness": int(f)}
            for c, o, f in zip(predicted.blocks_covered, predicted.blocks_covered_once,
                               predicted.fitness, strict=True)
        ],
        "model_fitness": "steps" if cfg.correction == "fit" else cfg.model_fitness,
        "correction": cfg.correction,
        "model_error_before": _number(error_before),
        "model_error_after": _number(errors[0]),
        "used_gait_ids": model_ga.used_gait_ids(tests, cfg.budget).tolist(),
        "operational": format_turn_cycle(operational),
        "operational_fitness": int(op_fit),
        "operational_replaced": bool(replaced),
        "robot_seconds": round(float(seconds_of_tests(tests, cfg.budget).sum()), 3),
        **fit_record,
    }
    pop, carried = state.cga_pop, state.search
    if search is not None:
        search.on_corrected(models, model_effects, operational)
        pop, carried = search.pop, search.chain
        record["search"] = search.record
    new = PALState(state.generation, pop, models, tuple(model_effects), operational,
                   op_score, op_fit, state.base, observed, carried, *structure)
    return new, record


def choose_tests(state: PALState, rng: np.random.Generator, cfg: PALConfig) -> np.ndarray:
    """The turn cycles to run: the CGA's best and two more
    (:mod:`pac_host.learning.test_selection`)."""
    best = state.cga_pop[0]
    pert = perturbations(best, rng, cfg)
    if cfg.tests == "paper":
        return np.concatenate([best[None], pert])
    row_var = state.models.var(axis=0).sum(axis=-1)
    hopeful = None
    if cfg.search_models > 1:  # the best was chosen for being sure: test the model's hope too
        alone = cga.fitness(state.models[0], state.cga_pop, cfg.budget, state.model_effects)
        hopeful = state.cga_pop[int(np.argmax(alone))]
    explored = (state.search or {}).get("explore") if cfg.explore > 0 else None
    if explored is not None:  # the best on a plausible table takes that place
        hopeful = np.array(explored, dtype=np.int64)
    return test_selection.choose(best, pert, state.cga_pop, state.models, row_var, cfg.budget,
                                 state.model_effects, hopeful=hopeful,
                                 teach=test_selection.TEACHING_ROWS if cfg.tests == "rows" else 0)


def _fit_correction(state: PALState, tests: np.ndarray, results: list[TestResult],
                    rng: np.random.Generator, cfg: PALConfig):
    """The whole-table correction from every observed step (:mod:`pac_host.learning.model_fit`),
    then
    the model GA (``cfg.method``) on the rows these tests used, if ``model_generations``."""
    if any(r.poses is None for r in results):
        raise InputError("model correction 'fit' needs the robot's observed paths; this observer "
                         "reports coverage counts only (use --correction ga)")
    new = tuple(model_fit.Observed(model_fit.expand_ids(t, cfg.budget)[: len(r.poses) - 1],
                                   np.asarray(r.poses)) for t, r in zip(tests, results,
                                                                        strict=True))
    observed = tuple(state.observed) + new
    base = state.base or GaitTable(state.models[0], state.model_effects)
    due = model_fit.structure_due(len(observed), state.structure_runs)
    post = model_fit.correct(base, observed, rng, cfg.structure, cfg.model_config().scale,
                             None if due else tuple(state.structure), cfg.refine_effects)
    structure = (tuple(post.selected), len(observed)) if due else (state.structure,
                                                                    state.structure_runs)
    size = cfg.model_population
    if cfg.model_generations > 0:
        used = model_ga.used_gait_ids(tests, cfg.budget)
        error_fn = model_ga.step_error(tests, [r.poses for r in results], cfg.budget,
                                       post.effects)
        models, errors = model_ga.evolve(
            post.sample(size, rng, rows=used), tests, None, cfg.model_generations, rng,
            cfg.method, cfg.model_config(), post.effects, error_fn)
    else:
        models = post.sample(size, rng)
        errors = model_ga.step_error(tests, [r.poses for r in results], cfg.budget,
                                     post.effects)(models[:1])
    record = {"structure": [str(e) for e in post.selected], "structure_selected": due,
              "evidence": post.evidence.tolist(),
              "row_sd": post.sd.round(4).tolist()}
    return models, errors, post.effects, observed, record, structure


class _AnytimeSearch:
    """The search of one punctuation: while the robot walks the tests (in a worker thread, on a
    real robot) it searches without a budget on the model the tests were chosen on; once the
    tests have corrected the model, it spends its budget of evaluations on the corrected one,
    so the next tests come from a search of the freshest model."""

    def __init__(self, state: PALState, rng: np.random.Generator, cfg: PALConfig) -> None:
        self.state, self.rng, self.cfg = state, rng, cfg
        self.pop = state.cga_pop
        self.chain = state.search
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
        self.pop, rec, chain = anytime.advance(
            self.state.models[0], self.pop, None, self.rng, self.cfg.budget,
            self.state.model_effects, self.cfg.search,
            cancelled=lambda: self.cancelled or not self.walking.is_set(), chain=carried,
            placement=self.cfg.placement_error(),
            models=_pooled_models(self.state.models, self.cfg),
            length_cost=self.cfg.kick_length_cost, shorten_after=self.cfg.shorten_after,
            windows=self.cfg.shorten_windows)
        self.chain = chain.to_json()
        self.walking_evaluations = rec["evaluations"]
        self.walking_best = rec.get("best_score", -1)

    def on_corrected(self, models: np.ndarray, effects: Sequence[Effect],
                     operational: np.ndarray) -> None:
        """Spend the budget on the corrected model ``models[0]``, from the population ranked
        on it, its sources the library and the search's best and the ``operational`` turn
        cycle from the model before (one the same as another adds no start:
        :func:`pac_host.search.shapes.starts`); with ``cfg.search_chains`` above one, the
        other chains each from its own point (:meth:`_other_chains`); with ``cfg.explore``, a
        share of it on ``models[1]`` (a draw from the posterior), from the best found."""
        from pac_host.search import anytime
        from pac_host.search.local import Chain

        library = shapes.load(self.cfg.shapes)

        def sources(*found: np.ndarray) -> tuple[list, list]:
            """The library's sources of starts, and the turn cycles found on the model before
            (as sources: the library's too unless ``cfg.library_restarts``); none without a
            library."""
            if not library.shapes:
                return [], []
            carried = [shapes.carried(x, self.state.models[0], self.state.model_effects)
                       for x in found]
            if self.cfg.library_restarts:
                return library.sources(), carried
            return library.sources() + carried, []

        rank, _ = _ranking(models, self.pop, self.cfg, effects)
        pop = self.pop[np.argsort(-rank, kind="stable")]
        carried = None if self.chain is None else Chain.from_json(self.chain)
        others = [Chain.from_json(doc) for doc in (self.chain or {}).get("others", [])]
        budget = self.cfg.search_evaluations
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
                                   finish=self.cfg.finish_moves)

        self.pop, rec, chain = search(self.rng, carried, (self.pop[0], operational))
        self.chain = chain.to_json()
        self.record = {"method": self.cfg.search, **rec}
        if self.cfg.search_chains > 1:
            self._other_chains(search, others)
        if explore > 0:
            found, done, _ = anytime.advance(models[1], self.pop[:1], explore, self.rng,
                                             self.cfg.budget, effects, self.cfg.search,
                                             placement=self.cfg.placement_error(),
                                             length_cost=self.cfg.kick_length_cost,
                                             shorten_after=self.cfg.shorten_after,
                                             windows=self.cfg.shorten_windows)
            self.chain["explore"] = found[0].tolist()
            self.record.update(explore=format_turn_cycle(found[0]),
                               explore_evaluations=done["evaluations"])
        if self.walking_evaluations is not None:
            self.record["evaluations_while_walking"] = self.walking_evaluations
            self.record["best_score_while_walking"] = self.walking_best

    def _other_chains(self, search: Callable, others: list) -> None:
        """Chains 1.. of ``cfg.search_chains``, each run by ``search`` as chain 0 was, but
        from its own carried point in ``others`` (the population's best on the first
        punctuation) with that point as its source, not the population's best or the
        operational turn cycle (both the best chain's finds), on a generator seeded from the
        run's; the best any chain found goes to the population's front, so it is tested (a tie
        keeps the earlier chain's). Given the best chain's find, every chain started there
        whenever it beat the chain's own point, and the chains ended most punctuations on one
        point: eight tries from one place, not eight searches (outside_library, 30 seeds: 26
        ended at 95% of the best known or more, against 13; docs/learning.md, "Chains kept
        apart")."""
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


def _ranking(models: np.ndarray, pop: np.ndarray, cfg: PALConfig, effects: Sequence[Effect]
             ) -> tuple[np.ndarray, np.ndarray]:
    """What an anytime search ranks turn cycles (P, 9, 2) by on the model ``models[0]`` (their
    coverage scores from the start, or with a placement error or pooled models their search
    scores pooled over the walks, as the search compares them), and their coverage scores on
    the model from the start."""
    error, pooled = cfg.placement_error(), _pooled_models(models, cfg)
    if error is None and pooled is None:
        fit = cga.fitness(models[0], pop, cfg.budget, effects)
        return fit, fit
    poses = START_POSE if error is None else error.stencil()
    return Scorer(models[0], cfg.budget, effects, poses, pooled).both(pop)


def advance_cga(state: PALState, generations: int, rng: np.random.Generator,
                cfg: PALConfig = PALConfig()) -> tuple[PALState, int]:
    """Run the CGA on the current best model; returns the state and the best model fitness.

    With an anytime search the turn cycles were searched at the punctuation, on the model it
    made: this only ranks them on that model, and counts the generations."""
    if cfg.search != "cga":
        rank, fit = _ranking(state.models, state.cga_pop, cfg, state.model_effects)
        order = np.argsort(-rank, kind="stable")
        state = replace(state, cga_pop=state.cga_pop[order],
                        generation=state.generation + generations)
        return state, int(fitness_of_score(fit[order[0]]))
    pop, best = cga.evolve(state.models[0], state.cga_pop, generations, rng, cfg.cga_config(),
                           state.model_effects)
    state = replace(state, cga_pop=pop, generation=state.generation + generations)
    return state, int(fitness_of_score(best[-1])) if len(best) else 0


def run(
    state: PALState,
    robot: Robot,
    rng: np.random.Generator,
    cfg: PALConfig = PALConfig(),
    on_punctuation: Callable[[PALState, dict], None] | None = None,
) -> PALState:
    """Punctuations at generation 0, ``interval``, ... up to ``cfg.generations``, with CGA
    generations between them. ``on_punctuation`` sees each record as it happens (to log it)."""
    while True:
        state, record = punctuate(state, robot, rng, cfg)
        if on_punctuation is not None:
            on_punctuation(state, record)
        if state.generation >= cfg.generations:
            return state
        step = min(cfg.interval, cfg.generations - state.generation)
        state, _ = advance_cga(state, step, rng, cfg)


def state_to_json(state: PALState, rng: np.random.Generator) -> dict:
    """Everything needed to resume a PAL run exactly: the state and the generator's state.

    Floats go through JSON's shortest round-trip representation, so a resumed run continues
    bit for bit.
    """
    return {
        "format": "pac-pal-state/1",
        "generation": state.generation,
        "cga_pop": state.cga_pop.tolist(),
        "models": state.models.tolist(),
        "model_effects": [e.to_json() for e in state.model_effects],
        "operational": state.operational.tolist(),
        "operational_score": state.operational_score,
        "operational_fitness": state.operational_fitness,
        "base": None if state.base is None else state.base.to_json(),
        "observed": [{"gait_ids": o.gait_ids.tolist(), "poses": o.poses.tolist(),
                      "cycles_since_power_on": o.cycles_since_power_on}
                     for o in state.observed],
        "search": state.search,
        "structure": [e.to_json() for e in state.structure],
        "structure_runs": state.structure_runs,
        "rng": rng.bit_generator.state,
    }


def _search_from_json(doc) -> dict | None:
    """The carried search of a state document, checked (None: none carried)."""
    if doc is None:
        return None
    from pac_host.search.local import Chain

    out = Chain.from_json(doc).to_json()
    others = doc.get("others") or []
    if not isinstance(others, list) or not all(isinstance(c, dict) for c in others):
        raise InputError("a carried search's other chains must be a list of chains")
    if others:  # chains 1.. of --search-chains
        out["others"] = [Chain.from_json(c).to_json() for c in others]
    if doc.get("explore") is not None:  # the best on a posterior draw, the next test
        out["explore"] = np.asarray(doc["explore"], dtype=np.int64).reshape(-1, 2).tolist()
    return out


def state_from_json(doc: dict) -> tuple[PALState, np.random.Generator]:
    """Inverse of :func:`state_to_json`."""
    from pac_host.model.effects import effect_from_json
    from pac_host.model.table import table_from_json

    if not isinstance(doc, dict) or doc.get("format") != "pac-pal-state/1":
        raise InputError("not a pac-pal-state/1 document")
    try:
        rng = np.random.default_rng()
        rng.bit_generator.state = doc["rng"]
        state = PALState(
            int(doc["generation"]),
            np.array(doc["cga_pop"], dtype=np.int64),
            np.array(doc["models"], dtype=np.float64),
            tuple(effect_from_json(e) for e in doc["model_effects"]),
            np.array(doc["operational"], dtype=np.int64),
            doc["operational_score"],
            doc["operational_fitness"],
            None if doc.get("base") is None else table_from_json(doc["base"], "PAL state base"),
            tuple(model_fit.Observed(np.array(o["gait_ids"], dtype=np.int64),
                                     np.array(o["poses"], dtype=np.float64),
                                     int(o.get("cycles_since_power_on", 0)))
                  for o in doc.get("observed", [])),
            _search_from_json(doc.get("search")),
            tuple(effect_from_json(e) for e in doc.get("structure", [])),
            None if doc.get("structure_runs") is None else int(doc["structure_runs"]),
        )
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(f"PAL state is incomplete or malformed ({e})") from None
    return state, rng
