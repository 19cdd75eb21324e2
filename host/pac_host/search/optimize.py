"""``pac-host optimize``: the strongest search for a turn cycle on a model that the project has.

Iterated local search with restarts (:mod:`pac_host.search.local`): climb single-gene changes
(a fresh random tenth of a gene's any-change neighbourhood each look) until none improves, kick
two genes (a closing kick, :mod:`pac_host.search.kicks`, for a loop the budget repeats) and climb
again, moving on to any local optimum at least as fit, and restart from a short CGA run after
``patience`` kicks in a row without progress. A chain's first start is the best of a library
of good sweeps re-expressed on the model (:mod:`pac_host.search.shapes`; ``shapes="none"``:
a short CGA run as well).
The search runs as ``chains`` independent chains, each seeded from ``SeedSequence([seed,
chain])``; ``jobs`` processes run them side by side, so for a budget in evaluations the result
depends on the seed alone. A budget in seconds is split among the chains by wall time (each
chain gets ``seconds`` when there are as many processes as chains).

With a placement error (``--placement-error``) every turn cycle is scored from a stencil of
start poses around the start (:mod:`pac_host.coverage.placement`), and the result also gives its
fitness
from start poses drawn with that error, which the stencil never saw.

With step noise (``--step-noise``) the search is for what the robot will deliver: every turn
cycle is scored by its mean fitness (or a quantile) over ``walks`` noisy walks with common
random numbers (:mod:`pac_host.coverage.noisy`; the same normals for every turn cycle and every
chain, drawn from the seed), each from a start pose drawn with the placement error if there is
one. A best of many candidates on K walks is partly their luck: each chain's best scored turn
cycles (:data:`FINALISTS`) are re-scored on fresh walks and the best there is the result, whose
figures are then measured on other fresh walks (:data:`FRESH_WALKS`): the mean with its 95%
interval, besides its noise-free figures.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed, wait
from dataclasses import asdict, dataclass

import numpy as np

from pac_host import limits
from pac_host.coverage import (
    DEFAULT_BUDGET,
    MAX_GENES,
    START_POSE,
    format_turn_cycle,
    simulate,
)
from pac_host.coverage.noisy import (
    NoisyWalks,
    check_quantile,
    check_walks,
    draw_normals,
    fitness_of_noisy_score,
    noisy_search_score,
)
from pac_host.coverage.noisy import summary as noisy_summary
from pac_host.coverage.placement import WALKS, PlacementError, placed_fitness, summary
from pac_host.errors import InputError
from pac_host.model.effects import Effect
from pac_host.model.step_noise import StepNoise
from pac_host.search import shapes
from pac_host.search.kicks import check_length_cost
from pac_host.search.local import SAMPLE, Objective, restarts
from pac_host.search.shorten import SHORTEN_AFTER, check_shorten_after

MAX_SECONDS = 7 * 24 * 3600.0
PLACED_STREAM = 1 << 20  # its seed stream, apart from the chains' (SeedSequence([seed, chain]))
# the noisy walks' streams: the search's (every chain's), the finalists' re-scoring, the report's
NOISE_STREAM, VALIDATE_STREAM, FRESH_STREAM = (PLACED_STREAM + i for i in (1, 2, 3))
# noisy walks a turn cycle is scored over in a search. Measured on the shifted table at 0.3,1
# (60 s, seed 1, mean over 400 fresh walks): 23.2 with 32 walks, 18.9 with 64 (twice the
# turn cycles scored; the finalists' fresh re-scoring takes the luck of few walks out)
WALKS_DEFAULT = 32
FINALISTS = 8  # a chain's best scored turn cycles re-scored on fresh walks
FRESH_WALKS = 400  # fresh noisy walks the finalists are re-scored on, and the result measured on


@dataclass(frozen=True)
class OptimizeConfig:
    """What a search is: budget of gait cycles per walk, stopping rule, chains, seed."""

    budget: int = DEFAULT_BUDGET
    seconds: float | None = None
    evaluations: int | None = None
    chains: int = 1
    seed: int = 0
    patience: int = 50
    kick_genes: int = 2
    # cm a gait cycle more of a kicked loop weighs in the closing kick's repair (0: none;
    # pac_host.search.kicks.SHORTER prefers shorter loops)
    kick_length_cost: float = 0.0
    # kicks without progress after which a chain tries shorter loops of its sweep
    # (pac_host.search.shorten; 0: never)
    shorten_after: int = SHORTEN_AFTER
    # whether shortening also re-sets windows of four consecutive genes (shorten.shorter_windows)
    shorten_windows: bool = True
    sample: float = SAMPLE  # share of a gene's any-change neighbourhood a climb scores a look
    placement: PlacementError | None = None  # score from a stencil of start poses
    # sweeps known to be good, re-expressed on the model as each chain's first start
    # (pac_host.search.shapes): "builtin", "none" or a pac-shapes/1 file
    shapes: str = "builtin"
    # score over noisy walks (pac_host.coverage.noisy): the step noise, the walks a turn cycle
    # is scored over and the quantile of their fitness ranked (None: the mean)
    step_noise: StepNoise | None = None
    walks: int = WALKS_DEFAULT
    quantile: float | None = None

    def check(self) -> None:
        if self.seconds is None and self.evaluations is None:
            raise InputError("give a budget: --seconds S or --evaluations N")
        if self.seconds is not None and not 0 < self.seconds <= MAX_SECONDS:
            raise InputError(f"--seconds must be in (0, {MAX_SECONDS:.0f}], got {self.seconds}")
        if self.evaluations is not None:
            limits.EVALUATIONS.check(self.evaluations, "--evaluations")
        limits.BUDGET.check(self.budget, "--budget")
        limits.CHAINS.check(self.chains, "--chains")
        if self.patience < 1 or not 1 <= self.kick_genes <= MAX_GENES:
            raise InputError("patience must be >= 1 and kick genes 1..9")
        check_length_cost(self.kick_length_cost)
        check_shorten_after(self.shorten_after)
        if not 0 < self.sample <= 1:
            raise InputError(f"--sample must be in (0, 1], got {self.sample}")
        shapes.load(self.shapes)
        if self.step_noise is not None:
            check_walks(self.walks, self.budget)
            check_walks(FRESH_WALKS, self.budget, "fresh walks")
            check_quantile(self.quantile)

    def noisy(self) -> bool:
        """Whether the search scores noisy walks."""
        return self.step_noise is not None and not self.step_noise.is_zero()


def stream_walks(rows: np.ndarray, effects: tuple[Effect, ...], cfg: OptimizeConfig,
                stream: int, walks: int) -> NoisyWalks:
    """``walks`` noisy walks of seed stream ``stream``: their normals, then (with a placement
    error) their start poses drawn from the same stream."""
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, stream]))
    z = draw_normals(rng, walks, cfg.budget)
    starts = cfg.placement.draw(walks, rng) if cfg.placement is not None else None
    return NoisyWalks(rows, cfg.step_noise, z, cfg.budget, effects,
                      START_POSE if starts is None else starts)


def _warm_up(rows: np.ndarray, budget: int, effects: tuple[Effect, ...]) -> None:
    """Load the compiled simulator (seconds the first time in a process) before a clock
    starts."""
    simulate(rows, np.zeros((1, MAX_GENES, 2), dtype=np.int64), budget, effects)


def run_chain(rows: np.ndarray, effects: tuple[Effect, ...], cfg: OptimizeConfig, chain: int,
              seconds: float | None, evaluations: int | None) -> dict:
    """Chain ``chain`` of a search: its best turn cycle (genes), score and progress."""
    _warm_up(rows, cfg.budget, effects)
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, chain]))
    noisy = {}
    if cfg.noisy():  # every chain walks the same normals: their scores compare
        walks = stream_walks(rows, effects, cfg, NOISE_STREAM, cfg.walks)
        noisy = {"step_noise": cfg.step_noise, "normals": walks.z, "quantile": cfg.quantile,
                 "walk_starts": None if cfg.placement is None else walks.starts,
                 "keep_finalists": FINALISTS}
        walks.figures(np.zeros((1, MAX_GENES, 2), dtype=np.int64))  # compiled before the clock
    t0 = time.perf_counter()
    objective = Objective(rows, cfg.budget, effects, limit=evaluations,
                          deadline=None if seconds is None else t0 + seconds,
                          placement=cfg.placement, **noisy)
    interrupted = False
    try:
        restarts(objective, rng, cfg.patience, cfg.kick_genes, sample=cfg.sample,
                 shapes=shapes.load(cfg.shapes).sources(noisy=cfg.noisy()),
                 length_cost=cfg.kick_length_cost,
                 shorten_after=cfg.shorten_after, windows=cfg.shorten_windows)
    except KeyboardInterrupt:  # Ctrl-C: the chain ends with the best found so far
        interrupted = True
    # chains are ranked by score: the best's coverage score, or its pooled search score when
    # the walks are from a placement's stencil or noisy
    score = (objective.best_score if cfg.placement is None and not cfg.noisy()
             else objective.best_search_score)
    res = {"chain": chain, "genes": None if objective.best is None else objective.best.tolist(),
           "score": score, "evaluations": objective.evaluations,
           "seconds": round(time.perf_counter() - t0, 3),
           "trace": [{"evaluations": e, "seconds": round(t, 3), "fitness": round(f, 3)}
                     for e, t, f in objective.trace]}
    if cfg.noisy():
        res["finalists"] = [{"genes": g.tolist(), "score": k} for k, g in objective.finalists]
    return {**res, "interrupted": True} if interrupted else res


class Interrupted(KeyboardInterrupt):
    """Ctrl-C stopped :func:`optimize`: ``result`` is what it returns, with the best found so
    far (None if nothing was scored yet)."""

    def __init__(self, result: dict | None) -> None:
        super().__init__()
        self.result = result


def optimize(rows: np.ndarray, cfg: OptimizeConfig, effects: Sequence[Effect] = (),
             jobs: int = 1, progress: Callable[[str, int, int], None] | None = None) -> dict:
    """Run the search; returns the best turn cycle, its figures, each chain's trace and the
    settings (JSON-ready). ``progress("chains", done, total)`` hears the start and each chain
    finish.

    A budget in seconds is the search's: its clock starts once the compiled simulator is
    loaded (a second or two in a fresh process), and scoring the result takes a moment more.
    Chains run one after another each get their share of the time left, so one that overran
    its share takes it from the next. Ctrl-C (KeyboardInterrupt) raises
    :class:`Interrupted` carrying the result so far."""
    cfg.check()
    effects = tuple(effects)
    n = cfg.chains
    seconds = None if cfg.seconds is None else cfg.seconds * min(jobs, n) / n
    evals = None if cfg.evaluations is None else [cfg.evaluations // n + (c < cfg.evaluations % n)
                                                  for c in range(n)]
    args = [(rows, effects, cfg, c, seconds, None if evals is None else evals[c])
            for c in range(n) if evals is None or evals[c] > 0]
    t0 = time.perf_counter()
    shapes.load(cfg.shapes)  # bad input before any progress is reported
    tell = progress or (lambda stage, done, total: None)
    tell("chains", 0, len(args))
    cut = False  # Ctrl-C cancelled chains not yet started
    if jobs <= 1 or len(args) <= 1:
        _warm_up(rows, cfg.budget, effects)
        start = time.perf_counter()
        chains = []
        for a in args:
            if cfg.seconds is not None:  # this chain's share of the time left
                left = cfg.seconds - (time.perf_counter() - start)
                a = (*a[:4], max(0.0, left / (len(args) - len(chains))), a[5])
            chains.append(run_chain(*a))
            tell("chains", len(chains), len(args))
            if chains[-1].get("interrupted"):
                break
    else:
        with ProcessPoolExecutor(max_workers=min(jobs, len(args))) as ex:
            futures = [ex.submit(run_chain, *a) for a in args]
            try:
                for n, _ in enumerate(as_completed(futures), 1):
                    tell("chains", n, len(args))
            except KeyboardInterrupt:  # the workers heard it too: their chains end now
                cut = True
                for f in futures:
                    f.cancel()
                wait(futures)
            chains = [f.result() for f in futures if not f.cancelled()]
    wall = time.perf_counter() - t0
    interrupted = cut or any(c.get("interrupted") for c in chains)
    chains = [c for c in chains if c["genes"] is not None]
    if not chains:
        if interrupted:
            raise Interrupted(None)
        walks = (cfg.walks if cfg.noisy() else
                 1 if cfg.placement is None else len(cfg.placement.stencil()))
        raise InputError(f"--evaluations {cfg.evaluations} is too few to score a turn cycle "
                         f"in a chain (each costs {walks})")
    best = max(chains, key=lambda c: c["score"])  # the first chain wins a tie
    genes = np.array(best["genes"], dtype=np.int64)
    placed = {}
    if cfg.noisy():
        genes, placed = _validate(rows, effects, cfg, chains)
    cov = simulate(rows, genes, cfg.budget, effects)
    if cfg.placement is not None and not cfg.noisy():
        rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, PLACED_STREAM]))
        fit = placed_fitness(rows, genes, cfg.placement, WALKS, rng, cfg.budget, effects)
        placed = {"stencil_fitness": best["trace"][-1]["fitness"] if best["trace"] else None,
                  "placed": summary(fit)}
    res = {
        "format": "pac-optimize/1",
        "turn_cycle": format_turn_cycle(genes),
        "genes": genes.tolist(),
        **cov.row(0),
        **placed,
        "evaluations": sum(c["evaluations"] for c in chains),
        "seconds": round(wall, 3),
        "settings": {**asdict(cfg), "jobs": jobs,
                     "step_noise": None if cfg.step_noise is None else cfg.step_noise.to_json(),
                     "method": "iterated local search with restarts"},
        "chains": chains,
    }
    if interrupted:
        raise Interrupted({**res, "interrupted": True})
    return res


def _validate(rows: np.ndarray, effects: tuple[Effect, ...], cfg: OptimizeConfig,
              chains: list[dict]) -> tuple[np.ndarray, dict]:
    """The result of a noisy search and its figures: the chains' finalists (each chain's best
    scored turn cycles on the search's walks) re-scored on :data:`FRESH_WALKS` fresh walks,
    the best there (as the search ranks: mean or quantile first) measured on as many others,
    which neither the search nor the choice saw."""
    found: dict[bytes, np.ndarray] = {}
    for c in chains:
        for g in [c["genes"]] + [f["genes"] for f in c.get("finalists", [])]:
            g = np.array(g, dtype=np.int64)
            found.setdefault(g.tobytes(), g)
    candidates = np.stack(list(found.values()))
    fig = stream_walks(rows, effects, cfg, VALIDATE_STREAM, FRESH_WALKS).figures(candidates)
    keys = noisy_search_score(fig[2], fig[4], cfg.budget, cfg.quantile)
    i = int(np.argmax(keys))  # the first (the best chain's best) wins a tie
    genes = candidates[i]
    fresh = stream_walks(rows, effects, cfg, FRESH_STREAM, FRESH_WALKS).figures(genes[None])
    fitness = fresh[2, 0]
    out = noisy_summary(fitness)
    if cfg.quantile is not None:
        out["quantile"] = cfg.quantile
        out["quantile_fitness"] = float(np.quantile(fitness, cfg.quantile,
                                                    method="inverted_cdf"))
    out["blocks_covered"] = round(float(fresh[0, 0].mean()), 3)
    best = max(chains, key=lambda c: c["score"])
    search = fitness_of_noisy_score(best["score"], cfg.budget, cfg.walks, cfg.quantile)
    return genes, {"step_noise": cfg.step_noise.to_json(), "walks": cfg.walks,
                   "quantile": cfg.quantile,
                   # the search's best on the search's walks: what the luck of K walks says
                   "search_best_fitness": round(float(search), 3),
                   "finalists": {"turn_cycles": len(candidates), "walks": FRESH_WALKS,
                                 "chosen_mean": round(float(fig[2, i].mean()), 3)},
                   "fresh": out}


def best_over_time(chains: list[dict]) -> list[tuple[float, int]]:
    """(seconds, best fitness so far) over all chains, as if they ran side by side."""
    points = sorted((t["seconds"], t["fitness"]) for c in chains for t in c["trace"])
    out: list[tuple[float, int]] = []
    for t, f in points:
        if not out or f > out[-1][1]:
            out.append((t, f))
    return out
