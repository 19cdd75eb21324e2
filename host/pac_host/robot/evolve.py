"""`pac-host evolve`: PAL (DESIGN.md 2.5) with a robot behind the serial link.

Everything a run produces lives in one output directory:

- ``config.json``: the run's settings (``--resume`` reads them back, so a resumed run is the
  same run);
- ``observations.jsonl``: every observation, appended and flushed before it is used (start
  poses, the pose after each gait cycle, manual counts), including those of a run cut short;
- ``log.jsonl``: one line per punctuation (tests, observed and predicted figures, run ids,
  model fitness before and after the model GA, the best model, the operational solution, and
  ``recovery``: the link's retries, resyncs, dropped reports and redone tests, counted and
  listed);
- ``runs.jsonl``: the observed runs in the format of DESIGN.md 4 (input to diagnosis);
- ``model.json`` (pac-gait-table/1) and ``turn_cycle.json``: the current best model and the
  operational solution;
- ``coverage_path.png`` and ``learning_progress.png``;
- ``state.json``: the PAL state and generator after the last complete punctuation.

Results depend only on the seed (and what the robot does): the CGA and model GA draw from one
seeded generator saved in ``state.json``, and each run's tracker noise in the emulator is seeded
by the run's identity.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import get_type_hints

import numpy as np

from pac_host import limits
from pac_host.coverage import START_POSE, detect_blocks, format_turn_cycle
from pac_host.errors import TOOLKIT_ERRORS, InputError, PacError
from pac_host.experiments.experiment import ExperimentConfig, initial_population
from pac_host.files import write_atomic
from pac_host.learning import pal
from pac_host.learning.config import model_generations_for
from pac_host.model.table import GaitTable, resolve_table, save_table
from pac_host.robot.connect import Connection
from pac_host.robot.linked import AppendLog, LinkedRobot
from pac_host.typed_values import coerce

CONFIG_FORMAT = "pac-evolve-config/1"


@dataclass(frozen=True)
class EvolveConfig:
    """What defines a run (stored in config.json; resume reads it back)."""

    seed: int = 0
    method: str = "partial"
    model_fitness: str = "coverage"
    generations: int = 1000
    interval: int = 40
    model_generations: int | None = None  # None: 40 for the paper's GA, 0 on a fitted table
    cga_population: int = 128
    model_population: int = 64
    budget: int = 200
    initial_generations: int = 200
    model: str = "measured"
    # between punctuations: "cga" (interval CGA generations, the paper) or "ils" (anytime: a
    # budget of search evaluations on each corrected model); runs saved before this existed
    # were "cga"
    search: str = "cga"
    search_evaluations: int = 0
    search_while_walking: bool = False  # also search while the robot walks the tests
    robot: dict = field(default_factory=dict)  # what played the robot (a resume reuses it)
    correction: str = pal.PALConfig.correction
    structure: str = pal.PALConfig.structure
    tests: str = pal.PALConfig.tests
    operational: str = pal.PALConfig.operational
    placement: str = pal.PALConfig.placement
    search_models: int = pal.PALConfig.search_models
    search_chains: int = pal.PALConfig.search_chains  # runs saved before it: 1
    shapes: str = pal.PALConfig.shapes  # runs saved before the library: none
    explore: float = pal.PALConfig.explore  # runs saved before it: 0
    kick_length_cost: float = pal.PALConfig.kick_length_cost  # runs saved before it: 0
    shorten_after: int = pal.PALConfig.shorten_after  # runs saved before it: 0
    shorten_windows: bool = pal.PALConfig.shorten_windows  # runs saved before it: False
    library_restarts: bool = pal.PALConfig.library_restarts  # runs saved before it: False
    finish_moves: bool = pal.PALConfig.finish_moves  # runs saved before it: False
    refine_effects: bool = pal.PALConfig.refine_effects  # runs saved before it: False
    # runs saved before it: False
    operational_evidence: bool = pal.PALConfig.operational_evidence
    search_noise: bool = pal.PALConfig.search_noise  # runs saved before it: False

    def check(self) -> None:
        if self.method not in ("partial", "full"):
            raise InputError(f"--method must be partial or full, got {self.method!r}")
        if self.model_fitness not in ("coverage", "steps"):
            raise InputError(f"--model-fitness must be coverage or steps, "
                             f"got {self.model_fitness!r}")
        for name, bound in (("generations", limits.GENERATIONS),
                            ("initial_generations", limits.GENERATIONS),
                            ("model_generations", limits.MODEL_GENERATIONS),
                            ("interval", limits.INTERVAL),
                            ("cga_population", limits.CGA_POPULATION),
                            ("model_population", limits.MODEL_POPULATION),
                            ("budget", limits.BUDGET)):
            if getattr(self, name) is not None:  # model_generations None: by the correction
                bound.check(getattr(self, name), f"--{name.replace('_', '-')}")
        self.pal().check()

    def pal(self) -> pal.PALConfig:
        return pal.PALConfig(
            method=self.method, model_fitness=self.model_fitness,
            generations=self.generations, interval=self.interval,
            model_generations=model_generations_for(self.correction, self.model_generations),
            cga_population=self.cga_population,
            model_population=self.model_population, budget=self.budget,
            correction=self.correction, structure=self.structure, tests=self.tests,
            operational=self.operational, placement=self.placement, search=self.search,
            search_models=self.search_models, search_chains=self.search_chains,
            shapes=self.shapes, explore=self.explore,
            kick_length_cost=self.kick_length_cost, shorten_after=self.shorten_after,
            shorten_windows=self.shorten_windows, library_restarts=self.library_restarts,
            finish_moves=self.finish_moves, refine_effects=self.refine_effects,
            operational_evidence=self.operational_evidence,
            search_noise=self.search_noise and self.search != "cga",
            search_evaluations=self.search_evaluations,
            search_while_walking=self.search_while_walking and self.search != "cga")

    def for_counts_only(self) -> EvolveConfig:
        """The settings to use when the observer reports coverage counts, not paths: the
        paper's six coverage differences and its model GA (nothing else can use counts)."""
        return replace(self, correction="ga", model_fitness="coverage")

    def needs_paths(self) -> bool:
        return self.correction == "fit" or self.model_fitness == "steps"


class RunInterrupted(PacError):
    """The robot or observer failed mid-punctuation; what was observed is in the log."""


class EvolveDir:
    """The files of one evolve run."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.config = root / "config.json"
        self.state = root / "state.json"
        self.log = root / "log.jsonl"
        self.runs = root / "runs.jsonl"
        self.observations = root / "observations.jsonl"
        self.model = root / "model.json"
        self.turn_cycle = root / "turn_cycle.json"
        self.path_png = root / "coverage_path.png"
        self.progress_png = root / "learning_progress.png"


def _read_jsonl(path: Path) -> list[dict]:
    if not path.exists():
        return []
    out = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if line.strip():
            try:
                out.append(json.loads(line))
            except json.JSONDecodeError:
                raise InputError(f"{path}:{n}: not a JSON line; cannot resume") from None
    return out


def _run_generation(run_id: str) -> int:
    return int(run_id.split("-")[0].removeprefix("g"))


def error_on_used(model: np.ndarray, truth: np.ndarray, used: list[int]) -> dict:
    """Mean |model - truth| per component over the gait ids the tests used."""
    e = np.abs(np.asarray(model)[used] - truth[used]).mean(axis=0)
    return {"F": round(float(e[0]), 4), "T": round(float(e[1]), 4), "dH": round(float(e[2]), 4)}


def _start(d: EvolveDir, cfg: EvolveConfig) -> tuple[pal.PALState, np.random.Generator, bool]:
    """A fresh state; writes config.json. The bool says no punctuation is done yet."""
    if d.state.exists():  # a complete punctuation is there: never overwrite it by accident
        raise InputError(f"{d.root} holds an evolve run: use --resume {d.root} to continue it, "
                         "or another --out")
    d.root.mkdir(parents=True, exist_ok=True)
    for p in (d.log, d.runs, d.state):
        p.unlink(missing_ok=True)
    d.runs.touch()  # exists even when the observer gives counts, not paths
    save_config(d.root, cfg)
    model = resolve_table(cfg.model)
    pcfg = cfg.pal()
    init = initial_population(model, 0, ExperimentConfig(
        base_seed=cfg.seed, initial_generations=cfg.initial_generations, pal=pcfg))
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 1]))
    return pal.initial_state(model, rng, pcfg, init), rng, True


def save_config(root: Path, cfg: EvolveConfig) -> None:
    write_atomic(EvolveDir(root).config,
                  json.dumps({"format": CONFIG_FORMAT, **asdict(cfg)}, indent=1) + "\n")


def load_config(root: Path) -> EvolveConfig:
    d = EvolveDir(root)
    try:
        doc = json.loads(d.config.read_text())
    except FileNotFoundError:
        raise InputError(f"--resume {root}: no config.json there (not an evolve run)") from None
    except json.JSONDecodeError as e:
        raise InputError(f"{d.config}: not JSON ({e})") from None
    if doc.get("format") != CONFIG_FORMAT:
        raise InputError(f"{d.config}: not a {CONFIG_FORMAT} file")
    hints = get_type_hints(EvolveConfig)
    return EvolveConfig(**{k: coerce(v, hints[k], f"{d.config}: {k}")
                           for k, v in doc.items() if k in hints})


def _resume(d: EvolveDir) -> tuple[pal.PALState, np.random.Generator, bool]:
    """The state after the last complete punctuation; later lines of log and runs dropped."""
    if not d.state.exists():
        raise InputError(f"--resume {d.root}: no complete punctuation yet (no state.json); "
                         "start it again without --resume")
    try:
        state, rng = pal.state_from_json(json.loads(d.state.read_text()))
    except json.JSONDecodeError as e:
        raise InputError(f"{d.state}: not JSON ({e})") from None
    g = state.generation
    log = [r for r in _read_jsonl(d.log) if r["generation"] <= g]
    runs = [r for r in _read_jsonl(d.runs) if _run_generation(r["run_id"]) <= g]
    write_atomic(d.log, "".join(json.dumps(r) + "\n" for r in log))
    write_atomic(d.runs, "".join(json.dumps(r) + "\n" for r in runs))
    AppendLog(d.observations)({"type": "resume", "generation": g, "time": time.time()})
    return state, rng, False


def evolve(
    root: Path,
    cfg: EvolveConfig,
    conn: Connection,
    resume: bool = False,
    on_punctuation: Callable[[dict], None] | None = None,
    progress: Callable[..., None] | None = None,
) -> dict:
    """Run (or resume) PAL on the connected robot; returns the last punctuation's record.

    ``progress(stage, done, total)`` hears the punctuations ("punctuations": at the start,
    then as each ends) and, with a fourth argument (the run id), the tests and the gait cycles
    walked in each (see :class:`~pac_host.robot.linked.LinkedRobot`)."""
    cfg.check()
    d = EvolveDir(root)
    state, rng, fresh = _resume(d) if resume else _start(d, cfg)
    pcfg = cfg.pal()
    obs_log = AppendLog(d.observations)
    obs_log({"type": "session", "robot": conn.description, "observer": conn.observer.name,
             "time": time.time()})
    robot = LinkedRobot(conn.robot, conn.observer, conn.placer, cfg.budget, obs_log, cfg.seed,
                        START_POSE)
    robot.progress = progress
    records = _read_jsonl(d.log)
    model_name = resolve_table(cfg.model).name
    cga_s = 0.0
    total = len(records) + punctuations_left(state.generation, cfg, fresh)
    if not fresh:
        if state.generation >= cfg.generations:
            return records[-1] if records else {}
        state, cga_s = _advance(state, rng, cfg)
    if progress is not None:
        progress("punctuations", len(records), total)
    while True:
        t0 = time.perf_counter()
        robot.generation = state.generation
        model_before = state.models[0].copy()
        timer = _TimedRobot(robot)
        try:
            state, rec = pal.punctuate(state, timer, rng, pcfg, concurrent=True)
        except TOOLKIT_ERRORS as e:
            raise RunInterrupted(
                f"run {robot.current_run}: {e}. Everything observed is in {d.observations}; "
                f"`pac-host evolve --resume {d.root}` continues from the last complete "
                "punctuation") from None
        rec["run_ids"] = [f"g{rec['generation']}-t{i}" for i in range(len(rec["tests"]))]
        rec["model"] = state.models[0].round(6).tolist()
        if conn.truth is not None:
            used = rec["used_gait_ids"]
            rec["true_error_on_used"] = {"before": error_on_used(model_before, conn.truth, used),
                                         "after": error_on_used(state.models[0], conn.truth, used)}
        rec["recovery"] = _recovery_record(robot)
        between, at = timing_names(pcfg)
        rec["timing"] = {"robot_s": round(timer.seconds, 4), between: round(cga_s, 4),
                         at: round(time.perf_counter() - t0 - timer.seconds, 4)}
        _persist(d, state, rng, rec, robot, timer, model_name, records, pcfg.search)
        if on_punctuation is not None:
            on_punctuation(rec)
        if progress is not None:
            progress("punctuations", len(records), total)
        if state.generation >= cfg.generations:
            return rec
        state, cga_s = _advance(state, rng, cfg)


def punctuations_left(generation: int, cfg: EvolveConfig, fresh: bool) -> int:
    """Punctuations still to come: at ``generation`` itself if none is done yet, then every
    ``interval`` generations and at ``cfg.generations``.

    >>> cfg = EvolveConfig(generations=100, interval=40)
    >>> punctuations_left(0, cfg, True), punctuations_left(40, cfg, False)
    (4, 2)
    """
    return int(fresh) + max(0, math.ceil((cfg.generations - generation) / cfg.interval))


def timing_names(pcfg: pal.PALConfig) -> tuple[str, str]:
    """The log's names for a punctuation's host seconds, for what ran: between punctuations
    (the CGA's generations; with an anytime search, only the ranking of its finds) and at the
    punctuation, besides the robot's time (the model's correction: the model GA, the fit, or
    the fit with the GA on top; with an anytime search, also its budget on the corrected
    model).

    >>> timing_names(pal.PALConfig(correction="ga", model_generations=40))
    ('cga_s', 'model_ga_s')
    >>> timing_names(pal.PALConfig(search="ils", search_evaluations=1000))
    ('ranking_s', 'model_fit_and_search_s')
    """
    if pcfg.correction == "ga":
        model = "model_ga"
    else:
        model = "model_fit_and_ga" if pcfg.model_generations else "model_fit"
    if pcfg.search == "cga":
        return "cga_s", f"{model}_s"
    return "ranking_s", f"{model}_and_search_s"


def _recovery_record(robot: LinkedRobot) -> dict:
    """This punctuation's recovery: counts, and each event without the per-run noise."""
    rec = robot.take_recovery()
    return {**rec.counts(), "events": rec.events}


def recovery_summary(root: Path) -> dict:
    """Retries, resyncs, dropped reports and redone tests over every punctuation logged."""
    total: dict[str, int] = {}
    for r in _read_jsonl(EvolveDir(root).log):
        for k, v in r.get("recovery", {}).items():
            if k != "events":
                total[k] = total.get(k, 0) + v
    return total


def _advance(state: pal.PALState, rng: np.random.Generator, cfg: EvolveConfig
             ) -> tuple[pal.PALState, float]:
    """CGA generations up to the next punctuation; returns the state and the seconds taken."""
    t0 = time.perf_counter()
    step = min(cfg.interval, cfg.generations - state.generation)
    state, _ = pal.advance_cga(state, step, rng, cfg.pal())
    return state, time.perf_counter() - t0


class _TimedRobot:
    """Counts the wall time spent on the robot (placing, loading, walking, observing)."""

    def __init__(self, robot: LinkedRobot) -> None:
        self.robot = robot
        self.seconds = 0.0
        self.results: list[pal.TestResult] = []

    def run_tests(self, tests: np.ndarray) -> list[pal.TestResult]:
        t0 = time.perf_counter()
        try:
            self.results = self.robot.run_tests(tests)
            return self.results
        finally:
            self.seconds += time.perf_counter() - t0


def path_title(rec: dict, punctuation: int) -> str:
    """coverage_path.png's title: the path it shows is the first test's, the model's best
    turn cycle walked on the robot at this punctuation, which may or may not be the robot's
    operational turn cycle.

    >>> print(path_title({"tests": ["12:9", "5:2"], "operational": "5:2"}, 3))
    punctuation 3: the model's best turn cycle, walked on the robot
    12:9 (operational: 5:2)
    """
    tested, operational = rec["tests"][0], rec["operational"]
    return (f"punctuation {punctuation}: the model's best turn cycle, walked on the robot\n"
            + (f"{tested} (the operational turn cycle)" if tested == operational
               else f"{tested} (operational: {operational})"))


def _persist(d: EvolveDir, state: pal.PALState, rng: np.random.Generator, rec: dict,
             robot: LinkedRobot, timer: _TimedRobot, model_name: str, records: list[dict],
             search: str = "cga") -> None:
    """Write a complete punctuation: runs, log line, model, turn cycle, plots, then the state
    (last, atomically: a crash before it makes resume redo this punctuation). ``search``:
    what ran between punctuations (the plots' axis)."""
    from pac_host.plots import coverage_path, learning_progress

    runs_log, log = AppendLog(d.runs), AppendLog(d.log)
    for r in robot.runs:
        runs_log(r)
    log(rec)
    records.append(rec)
    table = GaitTable(state.models[0], state.model_effects,
                      f"{model_name} evolved to generation {state.generation}")
    save_table(table, d.model)
    write_atomic(d.turn_cycle, json.dumps({
        "format": "pac-turn-cycle/1", "turn_cycle": format_turn_cycle(state.operational),
        "genes": state.operational.tolist(), "fitness_on_robot": state.operational_fitness,
        "generation": state.generation}, indent=1) + "\n")
    best = timer.results[0] if timer.results else None
    if best is not None and best.poses is not None:
        coverage_path(best.poses, detect_blocks(best.poses), d.path_png,
                      path_title(rec, len(records)), best.figures())
    learning_progress(records, d.progress_png, "PAL on the robot", search)
    write_atomic(d.state, json.dumps(pal.state_to_json(state, rng)) + "\n")
