"""The paper's experiment: PAL with full against partial recombination over many seeds.

For each seed (a starting population), the CGA's first population is the final population of a
long CGA run on the measured table; both methods then run PAL from it against the same actual
robot with the same random stream, so each seed gives a paired comparison. "Optimal" is the best
coverage fitness known on the actual robot: the best of long CGA runs on its table, raised to the
best any run of the experiment showed on it (the landscape is rugged: on the paper's task, 8
runs of 3000 generations end at 20 to 27, while one of 30 oracle runs finds 31).

The control ``oracle`` runs the same CGA from the same population on the actual robot's own
table (a perfect model, no model GA), tested the same way: the ceiling the co-evolved models
are measured against. How often it reaches the optimum says how hard the task is for the CGA
alone, in the generations given.

Everything is reproducible from ``base_seed``: run ``(seed, method)`` draws from
``SeedSequence([base_seed, seed, stage])``, so the results do not depend on ``jobs`` or on
which runs a resumed experiment skips.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable, Hashable, Sequence
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from pac_host import limits
from pac_host.coverage import fitness_of_score, format_turn_cycle, parse_turn_cycle, simulate
from pac_host.coverage.placement import HAND, WALKS, placed_fitness, summary
from pac_host.errors import InputError
from pac_host.experiments import stats
from pac_host.experiments.executors import Executor, local_executor
from pac_host.files import append_text, make_dirs, read_jsonl, write_atomic
from pac_host.learning import model_ga, pal
from pac_host.learning.config import NO_MODEL_GA, RUN_THE_GA, recombination_inert
from pac_host.model import best_known as known_records
from pac_host.model.effects import effective_rows
from pac_host.model.table import GaitTable, measured_table, shifted_table
from pac_host.search import cga
from pac_host.search.optimize import OptimizeConfig, run_chain

# seed streams; STAGE_PLACED draws the start poses a run's final turn cycle is walked from,
# STAGE_STEPS the actual robot's step noise in a run's tests (the same for each method of a
# seed), STAGE_EXPECTED the fresh walks each punctuation's operational turn cycle is measured
# on, on a noisy actual robot (by seed and punctuation: the same for each method, any --jobs),
# STAGE_OPTIMUM_EXPECTED the fresh walks the optimum runs' results and the runs' best
# operational turn cycles are compared on there (the same walks for each: common random
# numbers), STAGE_CONFIRMED the fresh walks the chosen optimum and the robot's record are
# measured on once chosen
(STAGE_INITIAL, STAGE_PAL, STAGE_OPTIMUM, STAGE_PLACED, STAGE_STEPS, STAGE_EXPECTED,
 STAGE_OPTIMUM_EXPECTED, STAGE_CONFIRMED) = range(8)
# fresh noisy walks of the actual robot behind each operational turn cycle's expected coverage
EXPECTED_WALKS = 400
# On a noisy actual robot the optimum runs' results and the OBSERVED_CANDIDATES highest
# operational turn cycles of the runs are compared over the same OBSERVED_WALKS fresh walks,
# and the one chosen is measured again over fresh walks: the highest of many noisy means is
# the luckiest (a sweep logged at 25.52 averaged 24.82 over 4000 walks; eight optimize chains
# that all found one sweep of 24.44 measured it at 23.97 to 25.18 over 400 walks each), and
# it sets the target every run is judged by
OBSERVED_CANDIDATES, OBSERVED_WALKS = 8, 4000
METHODS = ("full", "partial", "oracle")
# the optimum search's evaluations per run for the paper's 1000 generations; shorter runs get
# proportionately fewer (optimum_evaluations_for), down to the floor
OPTIMUM_EVALUATIONS = 5_000_000
OPTIMUM_EVALUATIONS_FLOOR = 200_000
PAPER_GENERATIONS = 1000
TARGET = 0.9  # punctuations to the target: operational coverage at 90% of the best known
FINAL_TARGET = 0.95  # and where a run ends, against the best known


@dataclass(frozen=True)
class ExperimentConfig:
    seeds: int = 5
    generations: int = 1000
    # default_methods(pal): the default PAL config runs no model GA, so full would be partial
    methods: tuple[str, ...] = ("partial", "oracle")
    base_seed: int = 0
    initial_generations: int = 1000  # the long CGA run on the model that seeds each population
    optimum_runs: int = 8
    optimum_generations: int = 3000
    # how the optimum is established: "cga" (long CGA runs, the paper profile) or "optimize"
    # (chains of pac_host.search.optimize with optimum_evaluations each)
    optimum_search: str = "cga"
    optimum_evaluations: int = OPTIMUM_EVALUATIONS
    best_known: int | None = None  # the best fitness known on the actual robot, if known
    pal: pal.PALConfig = field(default_factory=pal.PALConfig)

    def check(self) -> None:
        limits.SEEDS.check(self.seeds, "--seeds")
        limits.GENERATIONS.check(self.generations, "--generations")
        limits.GENERATIONS.check(self.initial_generations, "--initial-generations")
        limits.RUNS.check(self.optimum_runs, "--optimum-runs")
        limits.GENERATIONS.check(self.optimum_generations, "--optimum-generations")
        limits.BUDGET.check(self.pal.budget, "--budget")
        if self.optimum_search not in ("cga", "optimize"):
            raise InputError(f"optimum search must be cga or optimize, got {self.optimum_search}")
        limits.EVALUATIONS.check(self.optimum_evaluations, "--optimum-evaluations")
        if self.best_known is not None and self.best_known < 1:
            raise InputError(f"--best-known must be at least 1, got {self.best_known}")
        self.pal.check()
        bad = [m for m in self.methods if m not in METHODS]
        if bad or not self.methods or len(set(self.methods)) != len(self.methods):
            raise InputError(f"--methods takes {', '.join(METHODS)} (each once), got "
                             f"{','.join(self.methods)}")
        if self.pal.model_fitness not in model_ga.FITNESSES:
            raise InputError(f"--model-fitness takes {', '.join(model_ga.FITNESSES)}, got "
                             f"{self.pal.model_fitness!r}")
        if "full" in self.methods and recombination_inert(self.pal):
            raise InputError(f"--methods {','.join(self.methods)}: full differs from partial "
                             f"only in the model GA's recombination, and this profile "
                             f"{NO_MODEL_GA}; {RUN_THE_GA}")


def optimum_evaluations_for(generations: int) -> int:
    """Evaluations of each optimum run when none are given: 5,000,000 for the paper's 1000
    generations, in proportion to the run's generations, and at least 200,000.

    >>> optimum_evaluations_for(1000), optimum_evaluations_for(120), optimum_evaluations_for(8)
    (5000000, 600000, 200000)
    """
    return max(OPTIMUM_EVALUATIONS_FLOOR, OPTIMUM_EVALUATIONS * generations // PAPER_GENERATIONS)


def _rng(base: int, seed: int, stage: int, extra: int = 0) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([base, seed, stage, extra]))


def initial_population(model: GaitTable, seed: int, cfg: ExperimentConfig) -> np.ndarray:
    """The CGA's first population for a seed: the end of a long CGA run on the model."""
    rng = _rng(cfg.base_seed, seed, STAGE_INITIAL)
    ccfg = cfg.pal.cga_config()
    pop = cga.random_population(rng, ccfg.population)
    pop, _ = cga.evolve(model.rows, pop, cfg.initial_generations, rng, ccfg, model.effects)
    return pop


def optimum_run(actual: GaitTable, k: int, cfg: ExperimentConfig) -> dict:
    """One long search on the actual robot's table: its best turn cycle and fitness. With
    ``optimum_search`` "optimize", run k is chain k of ``pac-host optimize --seed BASE_SEED``
    with ``optimum_evaluations`` (starting from the runs' library of sweeps, ``--shapes``);
    with "cga", a CGA run of ``optimum_generations``. On an actual robot with step noise the
    chain searches the expected coverage over noisy walks (``optimize --step-noise``: its
    evaluations are walks) and its fitness is the result's mean over :data:`EXPECTED_WALKS`
    fresh walks (``expected``), as each punctuation's operational turn cycle is measured."""
    if cfg.optimum_search == "optimize":
        ocfg = OptimizeConfig(budget=cfg.pal.budget, evaluations=cfg.optimum_evaluations,
                              seed=cfg.base_seed, shapes=cfg.pal.shapes,
                              step_noise=None if actual.step_noise.is_zero()
                              else actual.step_noise)
        res = run_chain(actual.rows, tuple(actual.effects), ocfg, k, None,
                        cfg.optimum_evaluations)
        genes = np.array(res["genes"], dtype=np.int64)
        row = _optimum_figures(actual, genes, cfg)
        # no wall times: optimum.json is the same byte for byte wherever the runs ran
        return {"run": k, "turn_cycle": format_turn_cycle(genes), **row,
                "evaluations": res["evaluations"],
                "best_by_evaluations": [{"evaluations": t["evaluations"], "fitness": t["fitness"]}
                                        for t in res["trace"]]}
    rng = _rng(cfg.base_seed, k, STAGE_OPTIMUM)
    ccfg = cfg.pal.cga_config()
    pop = cga.random_population(rng, ccfg.population)
    pop, best = cga.evolve(actual.rows, pop, cfg.optimum_generations, rng, ccfg, actual.effects)
    return {"run": k, "turn_cycle": format_turn_cycle(pop[0]),
            **_optimum_figures(actual, pop[0], cfg),
            "best_by_generation": [int(fitness_of_score(b)) for b in best[::100]]}


def _optimum_figures(actual: GaitTable, genes: np.ndarray, cfg: ExperimentConfig) -> dict:
    """An optimum run's result on the actual robot: its coverage figures from the start; with
    step noise its fitness is what it delivers, the mean over :data:`OBSERVED_WALKS` fresh
    walks, the same for every run (``expected``), and its one noise-free walk's is
    ``noise_free_fitness``."""
    row = simulate(actual.rows, genes, cfg.pal.budget, actual.effects).row(0)
    if actual.step_noise.is_zero():
        return row
    expected = compared_on_robot(actual, genes, cfg)
    return {**row, "noise_free_fitness": row["fitness"], "fitness": expected["mean"],
            "expected": expected}


def pal_run(
    model: GaitTable,
    actual: GaitTable,
    seed: int,
    method: str,
    init_pop: np.ndarray,
    cfg: ExperimentConfig,
    log_path: Path | None,
) -> dict:
    """One PAL run; each punctuation is appended to the log as it happens. For ``oracle`` the
    CGA's model is the actual robot's table, unperturbed and never evolved. On an actual robot
    with step noise each punctuation's operational turn cycle is also measured by its expected
    coverage (:func:`expected_on_robot`, logged as ``operational_expected``), and the run's
    curve is that expectation, not the one walk (``walked``)."""
    fields = {**_pal_fields(cfg.pal), "method": method, "generations": cfg.generations}
    if method == "oracle":
        fields.update(method="partial", model_population=1, model_generations=0,
                      correction="ga", tests="paper", search_models=1,  # the model is sure
                      known_step_noise=None if actual.step_noise.is_zero()
                      else actual.step_noise.to_json())  # and so is its noise
        model = actual
    pcfg = pal.PALConfig(**fields)
    rng = _rng(cfg.base_seed, seed, STAGE_PAL)
    robot = pal.SimulatedRobot(actual, pcfg.budget, rng=_rng(cfg.base_seed, seed, STAGE_STEPS))
    state = pal.initial_state(model, rng, pcfg, init_pop)
    curve: list[tuple[int, int | float]] = []
    walked: list[int] = []
    seconds: list[float] = []
    truth = effective_rows(actual.rows, actual.effects)

    def log(st: pal.PALState, record: dict) -> None:
        record["method"] = method
        walked.append(record["operational_fitness"])
        figure = record["operational_fitness"]
        if not actual.step_noise.is_zero():
            record["operational_expected"] = expected_on_robot(actual, st.operational, seed,
                                                               len(curve), cfg)
            figure = record["operational_expected"]["mean"]
        curve.append((record["generation"], figure))
        seconds.append(record["robot_seconds"])
        record["model_error"] = _model_error(effective_rows(st.models[0], st.model_effects), truth)
        record["model"] = st.models[0].round(6).tolist()
        if log_path is not None:  # one write per line: appends stay whole
            append_text(log_path, json.dumps({"seed": seed, **record}) + "\n")

    state = pal.run(state, robot, rng, pcfg, log)
    return {
        "seed": seed,
        "method": method,
        "generations": [g for g, _ in curve],
        "coverage": [f for _, f in curve],
        **({} if actual.step_noise.is_zero() else {"walked": walked}),
        "robot_hours": _hours(seconds),
        "operational": format_turn_cycle(state.operational),
        "placed": _placed(actual, state.operational, seed, cfg),
        "final_model_error": _model_error(effective_rows(state.models[0], state.model_effects),
                                          truth),
        "final_model": state.models[0].round(6).tolist(),
    }


def expected_on_robot(actual: GaitTable, turn_cycle: np.ndarray, seed: int, punctuation: int,
                      cfg: ExperimentConfig, stage: int = STAGE_EXPECTED,
                      walks: int = EXPECTED_WALKS) -> dict:
    """What a turn cycle delivers on the noisy actual robot: its mean fitness over ``walks``
    fresh noisy walks (the compiled kernel, :mod:`pac_host.coverage.noisy`) drawn from the
    run's seed and ``punctuation`` (0, 1, ...), with the mean's 95% interval:
    ``{"mean", "interval", "walks"}``."""
    from pac_host.coverage.noisy import NoisyWalks, draw_normals
    from pac_host.learning.operational import Estimate

    z = draw_normals(_rng(cfg.base_seed, seed, stage, punctuation), walks, cfg.pal.budget)
    fit = NoisyWalks(actual.rows, actual.step_noise, z, cfg.pal.budget,
                     actual.effects).figures(np.asarray(turn_cycle)[None])[2, 0]
    fit = fit.astype(np.float64)
    return Estimate(float(fit.mean()), float(fit.std(ddof=1) / np.sqrt(fit.size)),
                    int(fit.size)).to_json()


def compared_on_robot(actual: GaitTable, turn_cycle: np.ndarray, cfg: ExperimentConfig,
                      stage: int = STAGE_OPTIMUM_EXPECTED) -> dict:
    """A candidate for the best known on the noisy actual robot: its mean over
    :data:`OBSERVED_WALKS` fresh walks, the same walks for every candidate (common random
    numbers: candidates differ by their turn cycles, not their draws). ``stage``
    :data:`STAGE_CONFIRMED`: the walks the chosen one is measured on again, free of the luck
    that chose it."""
    return expected_on_robot(actual, turn_cycle, 0, 0, cfg, stage, OBSERVED_WALKS)


def figures_of(actual: GaitTable) -> str:
    """What the experiment's coverage figures are: one walk, or on a noisy actual robot the
    expectation over fresh walks."""
    return "one walk" if actual.step_noise.is_zero() else f"expected over {EXPECTED_WALKS} walks"


def _hours(seconds: Sequence[float]) -> list[float]:
    """Cumulative robot hours after each punctuation."""
    return np.round(np.cumsum(seconds) / 3600.0, 4).tolist()


def punctuations_to(coverage: Sequence[int], target: float) -> int | None:
    """How many punctuations until the operational coverage first reached ``target``."""
    for i, c in enumerate(coverage):
        if c >= target:
            return i + 1
    return None


def robot_time_report(runs: list[dict], best_known: int, figures: str = "one walk") -> dict:
    """Per method: punctuations and robot hours to 90% of the best known, and where runs end
    (each run's ``coverage``: ``figures`` says whether one walk or an expectation).

    Seeds that never reach the target count as not reached (beyond any figure) in the
    median, so a median over seeds most of which missed is reported as None.
    """
    out: dict = {}
    by: dict[str, list[dict]] = {}
    for r in runs:
        by.setdefault(r["method"], []).append(r)
    for m, rs in by.items():
        to = [r["punctuations_to_target"] for r in rs]
        hours = [r["robot_hours"][n - 1] if n else None for r, n in zip(rs, to, strict=True)]
        key = [n if n is not None else np.inf for n in to]
        med = float(np.median(key)) if key else None
        reached = [n for n in to if n is not None]
        out[m] = {
            "seeds": len(rs),
            "reached_target": len(reached),
            "median_punctuations_to_target": med if med is not None and np.isfinite(med)
            else None,
            "punctuations_to_target_range": [min(reached), max(reached)] if reached else None,
            "median_robot_hours_to_target": (
                float(np.median([h if h is not None else np.inf for h in hours]))
                if reached and np.isfinite(med) else None),
            "ended_at_final_target": sum(r["coverage"][-1] >= FINAL_TARGET * best_known
                                         for r in rs),
            "median_final_over_best_known": round(float(np.median(
                [r["coverage"][-1] / best_known for r in rs])), 4),
            "mean_placed_fitness": (round(float(np.mean([r["placed"]["mean"] for r in rs])), 2)
                                    if all("placed" in r for r in rs) else None),
            "robot_hours_per_run": round(float(np.median([r["robot_hours"][-1] for r in rs])),
                                         3),
        }
    return {"best_known": best_known, "target": TARGET, "final_target": FINAL_TARGET,
            "figures": figures, "methods": out}


def _model_error(model: np.ndarray, truth: np.ndarray) -> list[dict]:
    """|model - actual| per gait cycle id and component."""
    err = np.abs(model - truth)
    return [{"id": i, "F": round(float(e[0]), 4), "T": round(float(e[1]), 4),
             "dH": round(float(e[2]), 4)} for i, e in enumerate(err)]


def _pal_fields(p: pal.PALConfig) -> dict:
    return {k: getattr(p, k) for k in p.__dataclass_fields__}


def default_methods(p: pal.PALConfig) -> tuple[str, ...]:
    """The methods an experiment compares unless told: full, partial and the oracle; where
    recombination is inert full would be partial's run again, so partial and the oracle.

    >>> default_methods(pal.PALConfig(correction="ga")), default_methods(pal.PALConfig())
    (('full', 'partial', 'oracle'), ('partial', 'oracle'))
    """
    return tuple(m for m in METHODS if not (m == "full" and recombination_inert(p)))


def read_complete_runs(log_path: Path, generations: int) -> dict[tuple[int, str], list]:
    """Punctuation records, by (seed, method), of runs whose log reaches ``generations``."""
    runs: dict[tuple[int, str], list] = {}
    for n, rec in read_jsonl(log_path, "the experiment's log"):  # a torn last line: ignored
        try:
            runs.setdefault((int(rec["seed"]), rec["method"]), []).append(rec)
            int(rec["generation"])
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{log_path}:{n}: not a punctuation record; cannot resume") from None
    return {k: v for k, v in runs.items()
            if any(r["generation"] >= generations for r in v)}


def reached_at(generations: Sequence[int], coverage: Sequence[int], optimum: int) -> int | None:
    """The CGA generation at which the operational coverage first reached the optimum."""
    for g, c in zip(generations, coverage, strict=True):
        if c >= optimum:
            return g
    return None


def compare(results: list[dict], cfg: ExperimentConfig, optimum: int) -> dict:
    """Per method: seeds reaching the optimum, the mean curve; and tests between methods."""
    by: dict[str, dict[int, dict]] = {m: {} for m in cfg.methods}
    for r in results:
        by[r["method"]][r["seed"]] = r
    out: dict = {"methods": {}}
    for m, runs in by.items():
        curves = np.array([runs[s]["coverage"] for s in sorted(runs)], dtype=float)
        reached = [runs[s]["reached_optimum_at"] for s in sorted(runs)]
        out["methods"][m] = {
            "seeds": len(runs),
            "reached_optimum": sum(r is not None for r in reached),
            "mean_coverage": curves.mean(axis=0).round(4).tolist() if len(curves) else [],
            "mean_final_coverage": float(curves[:, -1].mean()) if len(curves) else None,
            "mean_generation_reached": (float(np.mean([r for r in reached if r is not None]))
                                        if any(r is not None for r in reached) else None),
        }
    if "oracle" in by:  # paired with the ceiling: as good as a perfect model on that seed?
        ceiling = {s: r["coverage"][-1] for s, r in by["oracle"].items()}
        for m, runs in by.items():
            seeds = [s for s in sorted(runs) if s in ceiling]
            if m == "oracle" or not seeds:
                continue
            finals = [runs[s]["coverage"][-1] for s in seeds]
            ceilings = [ceiling[s] for s in seeds]
            out["methods"][m]["matched_oracle"] = sum(
                f >= c for f, c in zip(finals, ceilings, strict=True))
            out["methods"][m]["final_coverage_vs_oracle_wilcoxon"] = stats.wilcoxon_signed_rank(
                finals, ceilings)
            out["methods"][m]["final_coverage_over_oracle"] = round(
                float(np.mean(finals)) / max(float(np.mean(ceilings)), 1e-9), 4)
    if {"full", "partial"} <= set(cfg.methods):
        f, p = out["methods"]["full"], out["methods"]["partial"]
        out["tests"] = {
            "reached_optimum_fisher_exact_p": stats.fisher_exact(
                p["reached_optimum"], p["seeds"] - p["reached_optimum"],
                f["reached_optimum"], f["seeds"] - f["reached_optimum"]),
            **partial_against_full(
                {s: r["coverage"] for s, r in by["partial"].items()},
                {s: r["coverage"] for s, r in by["full"].items()}),
        }
    return out


def partial_against_full(partial: dict[Hashable, Sequence[int]],
                         full: dict[Hashable, Sequence[int]]) -> dict:
    """The paper's question over the seeds both recombinations ran (by seed, or any sortable
    key naming a seed, the operational coverage after each punctuation): paired two-sided
    Wilcoxon tests of the final coverage and of the mean over the punctuations, and on how
    many seeds partial ends higher or lower.

    >>> t = partial_against_full({0: [3, 9], 1: [4, 8]}, {0: [3, 7], 1: [4, 8]})
    >>> t["final_partial_higher"], t["final_partial_lower"], t["final_coverage_wilcoxon"]["n"]
    (1, 0, 1)
    """
    seeds = sorted(set(partial) & set(full))
    fin_p = [partial[s][-1] for s in seeds]
    fin_f = [full[s][-1] for s in seeds]
    return {
        "seeds": len(seeds),
        "final_coverage_wilcoxon": stats.wilcoxon_signed_rank(fin_p, fin_f),
        "mean_coverage_wilcoxon": stats.wilcoxon_signed_rank(
            [float(np.mean(partial[s])) for s in seeds], [float(np.mean(full[s])) for s in seeds]),
        "final_partial_higher": sum(a > b for a, b in zip(fin_p, fin_f, strict=True)),
        "final_partial_lower": sum(a < b for a, b in zip(fin_p, fin_f, strict=True)),
        "note": "paired over seeds (same starting population); two-sided; "
                "Wilcoxon statistic is the rank sum of seeds where partial is higher",
    }


def _map(fn: Callable, args: list[tuple], jobs: int | Executor,
         done: Callable[[object], None] | None = None) -> list:
    """Map on the executor given, or on ``jobs`` local processes (see
    :mod:`pac_host.experiments.executors`)."""
    if isinstance(jobs, Executor):
        return jobs.map(fn, args, done)
    with local_executor(jobs) as ex:
        return ex.map(fn, args, done)


def pal_run_detached(*args) -> tuple[dict, str]:
    """:func:`pal_run` on a worker that cannot write this side's files: its log lines come back
    with the result, to be appended once the run is whole (a rerun never writes twice)."""
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "log.jsonl"
        result = pal_run(*args, log_path=log)
        return result, log.read_text() if log.exists() else ""


def _map_pal_runs(args: list[tuple], jobs: int | Executor, log_path: Path,
                  done: Callable[[object], None]) -> list[dict]:
    if not isinstance(jobs, Executor) or jobs.shares_files:
        return _map(partial(pal_run, log_path=log_path), args, jobs, done)

    def landed(res: tuple[dict, str]) -> None:
        if res[1]:
            append_text(log_path, res[1])
        done(res[0])
    return [r for r, _ in _map(pal_run_detached, args, jobs, landed)]


def run_experiment(
    out_dir: Path,
    cfg: ExperimentConfig = ExperimentConfig(),
    model: GaitTable | None = None,
    actual: GaitTable | None = None,
    jobs: int | Executor = 1,
    resume: bool = False,
    progress: Callable[[str, int, int], None] | None = None,
    options: dict | None = None,
) -> dict:
    """Run the experiment, writing log.jsonl as it goes and summary.json at the end.

    ``jobs``: local worker processes, or an :class:`~pac_host.experiments.executors.Executor` (a
    Dask
    cluster); the results do not depend on it. ``progress(stage, done, total)`` hears each
    stage start (``done`` 0) and each of its tasks finish: "optimum" (runs), "initial
    populations" (seeds), "pal" (runs)."""
    cfg.check()
    model = model or measured_table()
    actual = actual or shifted_table()
    make_dirs(out_dir)
    log_path = out_dir / "log.jsonl"
    done_runs = read_complete_runs(log_path, cfg.generations) if resume else {}
    if not resume and log_path.exists() and log_path.stat().st_size > 0:
        raise InputError(f"{log_path} exists: use --resume to continue it, or another --out")
    if options is not None and not resume:  # what a resume checks its options against
        write_atomic(out_dir / "config.json", json.dumps(options, indent=1) + "\n")
    if resume and log_path.exists():  # drop incomplete runs' lines; they are rerun identically
        write_atomic(log_path, "".join(json.dumps(r) + "\n"
                                       for recs in done_runs.values() for r in recs))

    def tick(stage: str, total: int):
        """The executor's callback for a stage's finished tasks; reports the stage's start."""
        count = [0]
        if progress and total:
            progress(stage, 0, total)

        def done(_):
            count[0] += 1
            if progress:
                progress(stage, count[0], total)
        return done

    opt_args = [(actual, k, cfg) for k in range(cfg.optimum_runs)]
    optimum_runs = _map(optimum_run, opt_args, jobs, tick("optimum", len(opt_args)))

    todo = [(s, m) for s in range(cfg.seeds) for m in cfg.methods if (s, m) not in done_runs]
    seeds_needed = sorted({s for s, _ in todo})
    pops = dict(zip(seeds_needed, _map(
        initial_population, [(model, s, cfg) for s in seeds_needed], jobs,
        tick("initial populations", len(seeds_needed))), strict=True))
    fresh = _map_pal_runs([(model, actual, s, m, pops[s], cfg) for s, m in todo],
                          jobs, log_path, tick("pal", len(todo)))
    results = fresh + [_result_from_log(recs, s, m, actual, cfg)
                       for (s, m), recs in done_runs.items()]
    top = max(optimum_runs, key=lambda r: r["fitness"])  # a tie: the first run
    searched = top["fitness"]
    observed = max(max(r["coverage"]) for r in results)
    chosen = {}
    if not actual.step_noise.is_zero():
        observed_tc, observed = observed_again(actual, log_path, cfg)
        tc = observed_tc if observed > searched else top["turn_cycle"]
        again = compared_on_robot(actual, parse_turn_cycle(tc), cfg, STAGE_CONFIRMED)
        optimum = again["mean"]
        chosen = {"turn_cycle": tc, "confirmed": again}
    else:
        optimum = max(searched, observed)
    write_atomic(out_dir / "optimum.json", json.dumps(
        {"fitness": optimum, "searched": searched, "observed": observed, **chosen,
         "runs": optimum_runs, "search": _optimum_search(cfg),
         "how": f"the best of {cfg.optimum_runs} {_optimum_search(cfg)['runs']} on the actual "
                "robot's table, and of every operational turn cycle the experiment's runs "
                "tested on it" + ("" if actual.step_noise.is_zero() else
                                  f" (the runs' results and the {OBSERVED_CANDIDATES} highest "
                                  f"operational ones compared over the same {OBSERVED_WALKS} "
                                  "fresh walks, the best measured again over fresh walks: "
                                  "confirmed)")}, indent=1) + "\n")
    best = best_known_on(actual, cfg, optimum)
    for r in results:
        r["reached_optimum_at"] = reached_at(r["generations"], r["coverage"], optimum)
        r["punctuations_to_target"] = punctuations_to(r["coverage"], TARGET * best["fitness"])
    results.sort(key=lambda r: (r["method"], r["seed"]))
    summary = {
        "format": "pac-experiment/1",
        "config": {**asdict(cfg), "pal": None, "methods": list(cfg.methods)},
        "pal_config": asdict(cfg.pal),
        "model": model.name,
        "actual": {"name": actual.name, "effects": [e.to_json() for e in actual.effects],
                   **({} if actual.step_noise.is_zero()
                      else {"step_noise": actual.step_noise.to_json()})},
        "optimum": optimum,
        "runs": results,
        "comparison": compare(results, cfg, optimum),
        "best_known": best,
        "figures": figures_of(actual),
        "robot_time": robot_time_report(results, best["fitness"], figures_of(actual)),
    }
    write_atomic(out_dir / "summary.json", json.dumps(summary, indent=1) + "\n")
    return summary


def observed_again(actual: GaitTable, log_path: Path, cfg: ExperimentConfig
                   ) -> tuple[str | None, float]:
    """The best of the :data:`OBSERVED_CANDIDATES` best operational turn cycles of the
    logged runs (by their logged means) measured again (:func:`compared_on_robot`, the walks
    the optimum runs' results are measured on, the same for any --jobs or resume): (its turn
    cycle, its mean), (None, 0.0) with none logged."""
    best: dict[str, float] = {}
    for line in log_path.read_text().splitlines():
        rec = json.loads(line)
        tc, mean = rec["operational"], rec["operational_expected"]["mean"]
        best[tc] = max(best.get(tc, mean), mean)
    top = sorted(best, key=lambda tc: (-best[tc], tc))[:OBSERVED_CANDIDATES]
    again = [compared_on_robot(actual, parse_turn_cycle(tc), cfg)["mean"] for tc in top]
    if not again:
        return None, 0.0
    i = int(np.argmax(again))
    return top[i], again[i]


def best_known_on(actual: GaitTable, cfg: ExperimentConfig, optimum: float) -> dict:
    """What robot time is measured against: the highest of the experiment's own optimum, the
    package's record for the actual robot (where it is a built-in one, at the records'
    budget: :mod:`pac_host.model.best_known`; on a robot with step noise its robust record at
    that noise, its turn cycle measured again over :data:`OBSERVED_WALKS` fresh walks, the
    walks the experiment's chosen optimum is confirmed on, or none) and ``cfg.best_known``
    (``--best-known``); with which it is (``used``: "optimum", "built-in" or "given") and the
    candidates. The record's own figure is a mean over a few hundred walks: a target set by it
    would carry its luck."""
    noisy = not actual.step_noise.is_zero()
    rec = (known_records.robust_for_table(actual, cfg.pal.budget) if noisy
           else known_records.for_table(actual, cfg.pal.budget))
    found = [(optimum, "optimum", "this experiment's optimum on the actual robot")]
    built_in = None
    if rec is not None:
        name, r = rec
        value = (compared_on_robot(actual, parse_turn_cycle(r["turn_cycle"]), cfg,
                                   STAGE_CONFIRMED)["mean"] if noisy else r["fitness"])
        what = (f"the best known on the built-in robot {name} with step noise "
                f"{r['step_noise']}, measured again over {OBSERVED_WALKS} fresh walks "
                f"(recorded {r['mean']} over {r['walks']})" if noisy
                else f"the best known on the built-in robot {name}")
        found.append((value, "built-in",
                      f"{what} ({r['turn_cycle']}; pac_host/model/best_known.json)"))
        built_in = {"robot": name, "turn_cycle": r["turn_cycle"], "fitness": value,
                    **({"step_noise": r["step_noise"], "walks": OBSERVED_WALKS,
                        "recorded": {"mean": r["mean"], "walks": r["walks"]}} if noisy
                       else {})}
    if cfg.best_known is not None:
        found.append((cfg.best_known, "given", "--best-known"))
    fitness, used, source = max(found, key=lambda f: f[0])  # a tie: the first, own optimum
    return {"fitness": fitness, "used": used, "source": source, "optimum": optimum,
            "built_in": built_in, "given": cfg.best_known}


def _optimum_search(cfg: ExperimentConfig) -> dict:
    if cfg.optimum_search == "optimize":
        return {"method": "pac-host optimize (iterated local search with restarts)",
                "runs": f"chains of pac-host optimize with {cfg.optimum_evaluations} "
                        "evaluations each", "seed": cfg.base_seed,
                "chains": cfg.optimum_runs, "evaluations_per_chain": cfg.optimum_evaluations}
    return {"method": "CGA", "runs": f"CGA runs of {cfg.optimum_generations} generations",
            "seed": cfg.base_seed, "generations": cfg.optimum_generations}


def _placed(actual: GaitTable, operational: np.ndarray, seed: int, cfg: ExperimentConfig
            ) -> dict:
    """A run's final operational turn cycle walked on the actual robot from start poses drawn
    as a hand placement leaves them: what a lab would see, not only the exact start's figure
    (seeded by the run's seed alone, so a resumed experiment gives the same figures)."""
    fit = placed_fitness(actual.rows, operational, HAND, WALKS,
                         _rng(cfg.base_seed, seed, STAGE_PLACED), cfg.pal.budget, actual.effects)
    return summary(fit)


def _result_from_log(recs: list[dict], seed: int, method: str, actual: GaitTable,
                     cfg: ExperimentConfig) -> dict:
    recs = sorted(recs, key=lambda r: r["generation"])
    noisy = not actual.step_noise.is_zero()
    return {"seed": seed, "method": method,
            "generations": [r["generation"] for r in recs],
            "coverage": [r["operational_expected"]["mean"] if noisy
                         else r["operational_fitness"] for r in recs],
            **({"walked": [r["operational_fitness"] for r in recs]} if noisy else {}),
            "robot_hours": _hours([r.get("robot_seconds", 0.0) for r in recs]),
            "operational": recs[-1]["operational"],
            "placed": _placed(actual, parse_turn_cycle(recs[-1]["operational"]), seed, cfg),
            "final_model_error": recs[-1]["model_error"], "final_model": recs[-1]["model"]}
