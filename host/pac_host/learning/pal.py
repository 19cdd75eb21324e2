"""Punctuated anytime learning (DESIGN.md 2.5): the CGA learns on the model while the model GA
corrects the model from periodic tests on the robot.

Every punctuation, the CGA's best turn cycle and two perturbations of it run on the robot (real
or simulated) and on every model; the model GA evolves the models towards the robot's results;
its best model becomes the CGA's model; the robot's operational turn cycle is replaced only when
the CGA's best does better on the robot.

The robot is anything with ``run_tests(tests) -> list[TestResult]`` (:class:`Robot`); the
simulated actual robot of the paper is :class:`SimulatedRobot`.

The loop is here; its settings (:mod:`~pac_host.learning.config`), state
(:mod:`~pac_host.learning.state`), tests (:mod:`~pac_host.learning.testing`), anytime search
(:mod:`~pac_host.learning.anytime_search`) and saved state
(:mod:`~pac_host.learning.persistence`) have modules of their own, whose public names this one
re-exports.

>>> import numpy as np
>>> from pac_host.model import measured_table, shifted_table
>>> robot = SimulatedRobot(shifted_table())
>>> state = initial_state(measured_table(), np.random.default_rng(0), PALConfig(cga_population=16))
>>> state, rec = punctuate(state, robot, np.random.default_rng(1), PALConfig(cga_population=16))
>>> len(rec["tests"]), rec["generation"]
(3, 0)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from pac_host.coverage import (
    START_POSE,
    fitness_of_score,
    format_turn_cycle,
    parse_turn_cycle,
    simulate,
)
from pac_host.diagnose.noise import StepNoiseFit
from pac_host.errors import InputError
from pac_host.learning import model_fit, model_ga
from pac_host.learning import operational as operational_rule
from pac_host.learning.anytime_search import (
    _AnytimeSearch,
    _ranking,
    carried_walks,
    search_walks,
)
from pac_host.learning.config import (
    CORRECTIONS,
    OPERATIONAL,
    PAPER,
    PALConfig,
    model_generations_for,
)
from pac_host.learning.persistence import state_from_json, state_to_json
from pac_host.learning.robot_time import seconds_of_tests
from pac_host.learning.state import PALState, initial_state
from pac_host.learning.testing import (
    Robot,
    SimulatedRobot,
    TestResult,
    choose_tests,
    perturbations,
    results_from_coverage,
)
from pac_host.model.step_noise import StepNoise
from pac_host.model.table import GaitTable
from pac_host.search import cga

__all__ = [
    "CORRECTIONS",
    "OPERATIONAL",
    "PAPER",
    "PALConfig",
    "PALState",
    "Robot",
    "SimulatedRobot",
    "TestResult",
    "advance_cga",
    "choose_tests",
    "initial_state",
    "model_error_fn",
    "model_generations_for",
    "perturbations",
    "punctuate",
    "results_from_coverage",
    "run",
    "state_from_json",
    "state_to_json",
]


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
    tests = operational_rule.with_repeat(choose_tests(state, rng, cfg), state.repeat)
    predicted = _predicted(state, tests, cfg)
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
    walks = _walked(state, tests, results)
    noise_fit = _step_noise(state, tests, results, cfg)
    choice = _Choice(operational, op_score, op_fit, replaced)
    if cfg.operational_evidence and noise_fit is not None and noise_fit.clear():
        # a noisy robot: every walk and the model's prediction decide, not the last walk
        choice = _by_evidence(state, tests, results, walks, noise_fit.noise, rng, cfg)
    operational, op_score, op_fit, replaced = (choice.operational, choice.score,
                                               choice.fitness, choice.replaced)
    estimates, repeat, error_var = choice.estimates, choice.repeat, choice.error_var
    op_walks = walks.get(operational_rule.key(operational), (op_fit,))

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
        "predicted": predicted,
        "model_fitness": "steps" if cfg.correction == "fit" else cfg.model_fitness,
        "correction": cfg.correction,
        "model_error_before": _number(error_before),
        "model_error_after": _number(errors[0]),
        "used_gait_ids": model_ga.used_gait_ids(tests, cfg.budget).tolist(),
        "operational": format_turn_cycle(operational),
        "operational_fitness": int(op_fit),
        "operational_replaced": bool(replaced),
        "operational_estimate": _logged_estimate(operational, op_walks, estimates, noise_fit),
        "test_walks": [len(walks[operational_rule.key(t)]) for t in tests],
        "robot_seconds": round(float(seconds_of_tests(tests, cfg.budget).sum()), 3),
        **fit_record,
    }
    if cfg.correction == "fit" or cfg.known_step_noise is not None:
        record["step_noise"] = None if noise_fit is None else noise_fit.to_json()
    if estimates:
        record["test_estimates"] = [estimates[operational_rule.key(t)].to_json() for t in tests]
        record["repeat"] = None if repeat is None else operational_rule.key(repeat)
        # the model's prediction error learnt from its track record (None: not yet)
        record["model_error_sd"] = None if error_var is None else round(error_var**0.5, 3)
    pop, carried = state.cga_pop, state.search
    # search_noise: the step noise the search walks the model with (clear estimates only)
    noise = (noise_fit.noise if cfg.search_noise and noise_fit is not None and noise_fit.clear()
             else None)
    if search is not None:
        search.on_corrected(models, model_effects, operational, noise)
        pop, carried = search.pop, search.chain
        record["search"] = search.record
    new = PALState(state.generation, pop, models, tuple(model_effects), operational,
                   op_score, op_fit, state.base, observed, carried, *structure, walks, repeat,
                   noise)
    return new, record


def _predicted(state: PALState, tests: np.ndarray, cfg: PALConfig) -> list[dict]:
    """The model's figures for the tests: one noise-free walk from the start, or with
    ``search_noise`` and a clear step noise estimate their means over the noisy walks the
    search last ranked with (each entry says over how many walks)."""
    noise, seed = carried_walks(state, cfg)
    if noise is None:
        p = simulate(state.models[0], tests, cfg.budget, state.model_effects)
        return [{"blocks_covered": int(c), "blocks_covered_once": int(o), "fitness": int(f)}
                for c, o, f in zip(p.blocks_covered, p.blocks_covered_once, p.fitness,
                                   strict=True)]
    from pac_host.coverage.noisy import NoisyWalks

    walks = search_walks(noise, seed, cfg)
    starts = walks["walk_starts"]
    fig = NoisyWalks(state.models[0], noise, walks["normals"], cfg.budget, state.model_effects,
                     START_POSE if starts is None else starts).figures(tests).mean(axis=2)
    return [{"blocks_covered": round(float(c), 3), "blocks_covered_once": round(float(o), 3),
             "fitness": round(float(f), 3), "expected_over_walks": len(walks["normals"])}
            for c, o, f in zip(fig[0], fig[1], fig[2], strict=True)]


def _walked(state: PALState, tests: np.ndarray, results: list[TestResult]
            ) -> dict[str, tuple[int, ...]]:
    """Every walk so far, these tests' added (a state saved before walks were kept: the
    operational turn cycle's one known walk)."""
    walks = dict(state.walks)
    if not walks and state.operational_fitness is not None:
        walks[operational_rule.key(state.operational)] = (int(state.operational_fitness),)
    for t, r in zip(tests, results, strict=True):
        k = operational_rule.key(t)
        walks[k] = walks.get(k, ()) + (int(r.fitness),)
    return walks


def _observed_tests(tests: np.ndarray, results: list[TestResult], budget: int
                    ) -> tuple[model_fit.Observed, ...]:
    """These tests as observed runs: the gait ids walked and the observed poses."""
    return tuple(model_fit.Observed(model_fit.expand_ids(t, budget)[: len(r.poses) - 1],
                                    np.asarray(r.poses))
                 for t, r in zip(tests, results, strict=True))


def _step_noise(state: PALState, tests: np.ndarray, results: list[TestResult],
                cfg: PALConfig) -> StepNoiseFit | KnownStepNoise | None:
    """With the "fit" correction, the robot's step noise estimated from every observed run
    (None: another correction, paths not observed, or no repeated steps yet); the noise itself
    where it is known (``cfg.known_step_noise``: the oracle control)."""
    known = cfg.known_noise()
    if known is not None:
        return KnownStepNoise(known)
    if cfg.correction != "fit" or any(r.poses is None for r in results):
        return None
    observed = tuple(state.observed) + _observed_tests(tests, results, cfg.budget)
    return model_fit.step_noise(observed)


# walked turn cycles besides the candidates whose predictions give the model's track record
TRACK_LIMIT = 64


class KnownStepNoise:
    """A step noise known, not estimated: what :class:`~pac_host.diagnose.noise.StepNoiseFit`
    says of an estimate (its noise; clear when not zero) for the noise as given."""

    def __init__(self, noise: StepNoise) -> None:
        self.noise = noise

    def clear(self) -> bool:
        return not self.noise.is_zero()

    def to_json(self) -> dict:
        return {"known": self.noise.to_json(), "clear": self.clear()}


@dataclass(frozen=True)
class _Choice:
    """A punctuation's operational turn cycle and what decided it."""

    operational: np.ndarray
    score: float | None  # its test score (the last walk's)
    fitness: int  # its last walk's fitness
    replaced: bool
    repeat: np.ndarray | None = None  # the turn cycle to walk again, if a decision needs it
    estimates: dict[str, operational_rule.Estimate] = field(default_factory=dict)
    error_var: float | None = None  # the model's error variance from its track record


def _by_evidence(state: PALState, tests: np.ndarray, results: list[TestResult],
                 walks: dict[str, tuple[int, ...]], noise, rng: np.random.Generator,
                 cfg: PALConfig) -> _Choice:
    """The operational turn cycle chosen on all its walks and the model's prediction with the
    estimated step ``noise`` (:mod:`pac_host.learning.operational`), a test to walk again where
    the decision needs it, and the model's error variance from its track record."""
    tested = range(len(tests)) if cfg.operational == "tested" else range(1)
    keys = [operational_rule.key(tests[i]) for i in tested]
    op_key = None if state.operational_score is None else operational_rule.key(state.operational)
    cands, names = [], []  # the operational turn cycle and every test (each is logged)
    for tc in ([] if op_key is None else [state.operational]) + list(tests):
        if operational_rule.key(tc) not in names:
            names.append(operational_rule.key(tc))
            cands.append(tc)
    decided = len(names)
    # and the model's track record: every other turn cycle walked (the latest TRACK_LIMIT)
    for k in [k for k in walks if k not in names][-TRACK_LIMIT:]:
        names.append(k)
        cands.append(parse_turn_cycle(k))
    mean, walk_sd, model_sd = operational_rule.model_walks(
        state.models, state.model_effects, np.stack(cands), cfg.budget, noise,
        np.random.default_rng(rng.integers(2**63)))
    sds = {k: operational_rule.pooled_sd(float(s), walks.get(k, ()))
           for k, s in zip(names, walk_sd, strict=True)}
    predicted = {k: float(m) for k, m in zip(names, mean, strict=True)}
    error_var = operational_rule.model_error_var(walks, predicted, sds)
    # the model's error for each candidate from the other turn cycles' record: its own walks
    # are the evidence against its prediction once, not twice
    own = {k: operational_rule.model_error_var(walks, predicted, sds, leave_out=k)
           for k in names[:decided]}
    estimates = {k: operational_rule.estimate(walks.get(k, ()), float(m), sds[k], float(d),
                                              own[k])
                 for k, m, d in list(zip(names, mean, model_sd, strict=True))[:decided]}
    tracked = all(v is not None for v in own.values())
    chosen, again = operational_rule.decide(
        op_key, estimates, keys,
        operational_rule.TRACKED_Z if tracked else operational_rule.DECISION_Z)
    repeat = None
    if again is not None:
        repeat = state.operational if again == op_key else tests[keys.index(again)].copy()
    if chosen is not None:
        i = list(tested)[keys.index(chosen)]
        return _Choice(tests[i].copy(), results[i].score, results[i].fitness, True, repeat,
                       estimates, error_var)
    walked = [i for i in range(len(tests)) if operational_rule.key(tests[i]) == op_key]
    score = results[walked[-1]].score if walked else state.operational_score
    last = walks.get(op_key, (state.operational_fitness,))[-1]
    return _Choice(state.operational, score, last, False, repeat, estimates, error_var)


def _logged_estimate(operational: np.ndarray, walks: Sequence[int],
                     estimates: dict, noise_fit: StepNoiseFit | KnownStepNoise | None) -> dict:
    """The operational turn cycle's expected fitness as logged: the evidence rule's estimate;
    else, on a robot without clear step noise, its walks' mean (each walk exact); with clear
    step noise but the last-walk rule, the walks' mean and standard error (interval None after
    one walk: its spread is unknown)."""
    k = operational_rule.key(operational)
    if k in estimates:
        return estimates[k].to_json()
    n = len(walks)
    if noise_fit is None or not noise_fit.clear():
        return operational_rule.estimate(walks, 0.0, 0.0, 0.0).to_json()
    if n < 2:
        return {"mean": round(float(np.mean(walks)), 2), "interval": None, "walks": n}
    return operational_rule.Estimate(float(np.mean(walks)),
                                     float(np.std(walks, ddof=1) / np.sqrt(n)), n).to_json()


def _fit_correction(state: PALState, tests: np.ndarray, results: list[TestResult],
                    rng: np.random.Generator, cfg: PALConfig):
    """The whole-table correction from every observed step (:mod:`pac_host.learning.model_fit`),
    then
    the model GA (``cfg.method``) on the rows these tests used, if ``model_generations``."""
    if any(r.poses is None for r in results):
        raise InputError("model correction 'fit' needs the robot's observed paths; this observer "
                         "reports coverage counts only (use --correction ga)")
    observed = tuple(state.observed) + _observed_tests(tests, results, cfg.budget)
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


def advance_cga(state: PALState, generations: int, rng: np.random.Generator,
                cfg: PALConfig = PALConfig()) -> tuple[PALState, int]:
    """Run the CGA on the current best model; returns the state and the best model fitness.

    With an anytime search the turn cycles were searched at the punctuation, on the model it
    made: this only ranks them on that model, and counts the generations."""
    if cfg.search != "cga":
        rank, fit = _ranking(state.models, state.cga_pop, cfg, state.model_effects,
                             *carried_walks(state, cfg))
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
