"""The settings of a PAL run (:class:`PALConfig`, DESIGN.md 2.5), checked as one, and the
paper's method as a set of them (:data:`PAPER`).

>>> PALConfig(**PAPER).check()
>>> model_generations_for("fit", None), model_generations_for("ga", None)
(0, 40)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import partial

from pac_host import limits
from pac_host.coverage import DEFAULT_BUDGET, placement
from pac_host.errors import InputError
from pac_host.learning import model_fit, model_ga, test_selection
from pac_host.model.step_noise import StepNoise, step_noise_from_json
from pac_host.search import cga, shapes
from pac_host.search.kicks import check_length_cost
from pac_host.search.shorten import check_shorten_after

CORRECTIONS = ("ga", "fit")
OPERATIONAL = ("best", "tested")


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
    # (docs/explanation/learning.md, "Eight search chains a punctuation"); 1: one chain, 8 in the
    # default profile. While the robot walks (search_while_walking) chain 0 alone searches
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
    # With the "fit" correction: whether the operational turn cycle is chosen on the evidence
    # of all its walks and the model's prediction once the robot's step noise is estimated
    # clearly above zero, a repeat test asked for when the walks cannot decide (True), or
    # replaced whenever one walk beats the last (False, runs saved before it). On a robot
    # without step noise the two are one rule (pac_host.learning.operational)
    operational_evidence: bool = False
    # With an anytime search and the "fit" correction: whether, once the robot's step noise is
    # estimated clearly above zero, the search ranks turn cycles by their expected coverage
    # over noisy walks of the model with that noise (common random numbers drawn from the
    # search's own generator; pac_host.coverage.noisy) and the tests' predictions are
    # expectations (True), or by one noise-free walk (False, runs saved before it and the
    # paper). Without a clear estimate the search is the noise-free one, figure for figure
    search_noise: bool = False
    # With search_noise and a clear estimate: the search's evaluations each punctuation are
    # ``search_evaluations`` times this. An evaluation is then one noisy walk, so a turn cycle
    # costs SEARCH_WALKS of them (pac_host.learning.anytime_search); a real robot's tests take
    # minutes a punctuation, against seconds for these walks
    noisy_search_scale: int = 1
    # The robot's step noise when it is known rather than estimated (its JSON form,
    # pac_host.model.step_noise; None: estimated from the observed steps): the oracle control
    # of an experiment on a noisy robot knows its robot as it knows its table
    known_step_noise: dict | None = None
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
        limits.NOISY_SEARCH_SCALE.check(self.noisy_search_scale, "noisy_search_scale")
        if self.search_noise and self.search == "cga":
            raise InputError("search_noise needs an anytime profile (the paper's CGA scores "
                             "one noise-free walk)")
        if self.known_step_noise is not None:
            step_noise_from_json(self.known_step_noise, "known step noise")
        if self.placement_error() is not None and self.search == "cga":
            raise InputError("--placement-error needs an anytime profile (the paper's CGA "
                             "scores from the exact start)")

    def known_noise(self) -> StepNoise | None:
        """The robot's step noise as given (:attr:`known_step_noise`), or None."""
        if self.known_step_noise is None:
            return None
        return step_noise_from_json(self.known_step_noise, "known step noise")

    def placement_error(self) -> placement.PlacementError | None:
        return placement.parse_placement(self.placement)


# The paper's method (DESIGN.md 2.5): PALConfig(**PAPER) runs it with today's exact results.
PAPER = {"correction": "ga", "tests": "paper", "operational": "best", "model_fitness": "coverage",
         "model_generations": 40}


def model_generations_for(correction: str, given: int | None) -> int:
    """Model GA generations per punctuation: as given, else the paper's 40 for its model GA
    and none on a fitted table (the GA on top was not measured to help:
    docs/explanation/learning.md)."""
    if given is not None:
        return given
    return PAPER["model_generations"] if correction == "ga" else 0


def recombination_inert(p: PALConfig | Mapping) -> bool:
    """Whether full and partial recombination are the same run: they differ only in the model
    GA, and with the whole-table fit and no model GA generations none runs. ``p``: a PAL
    config, or its JSON form (a summary's ``pal_config``)."""
    get = p.get if isinstance(p, Mapping) else partial(getattr, p)
    return get("correction") == "fit" and get("model_generations") == 0


# why recombination is inert, and what makes it matter (the CLI's refusals say both)
NO_MODEL_GA = "runs no model GA (it fits the model to every observed step)"
RUN_THE_GA = "use --profile paper, or --model-generations N to run the GA on top"
