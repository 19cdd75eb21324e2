"""What a PAL run carries from one punctuation to the next (:class:`PALState`, enough to resume
it) and where a run starts (:func:`initial_state`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pac_host.learning import model_ga
from pac_host.learning.config import PALConfig
from pac_host.model.step_noise import StepNoise
from pac_host.model.table import GaitTable
from pac_host.search import cga, shapes
from pac_host.search.kicks import loop_table


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
    # every walk on the robot: turn cycle (its text form) -> the fitness of each walk, in order
    walks: dict[str, tuple[int, ...]] = field(default_factory=dict)
    # the turn cycle a decision on the operational one asked to walk again at the next
    # punctuation (operational_evidence), None: no repeat asked
    repeat: np.ndarray | None = None
    # the robot's step noise as the last correction estimated it, when clearly above zero
    # (search_noise: what the search and the tests' predictions walk the model with), None:
    # none clear, or not searched with
    step_noise: StepNoise | None = None


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
    known = cfg.known_noise() if cfg.search_noise else None  # searched with from the first
    return PALState(0, cga_pop, models, tuple(model.effects), cga_pop[0].copy(), None, None,
                    model, step_noise=None if known is None or known.is_zero() else known)
