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
- ``state.json``: the PAL state and generator after the last complete punctuation, with that
  punctuation's log record and runs (written first: it marks a punctuation complete, see
  :func:`_persist`).

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
from pac_host.coverage.gaps import fill_gaps
from pac_host.errors import TOOLKIT_ERRORS, InputError, PacError, with_hint
from pac_host.experiments.experiment import ExperimentConfig, initial_population
from pac_host.files import append_text, cut_torn_line, read_jsonl, read_text, write_atomic
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
    noisy_search_scale: int = pal.PALConfig.noisy_search_scale  # runs saved before it: 1

    def check(self) -> None:
        """Every value in its range and the model file read: one line (InputError) before
        anything is opened or written."""
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
        try:
            resolve_table(self.model)
        except InputError as e:
            raise InputError(f"--model: {e}") from None

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
            noisy_search_scale=self.noisy_search_scale,
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
    """A log's records; a torn last line (a full disk, a crash) is ignored
    (:func:`pac_host.files.read_jsonl`)."""
    return [r for _, r in _numbered(path)]


def _numbered(path: Path) -> list[tuple[int, dict]]:
    out = read_jsonl(path, "the run's log")
    for n, r in out:
        if not isinstance(r, dict):
            raise InputError(f"{path}:{n}: not a JSON object; cannot resume")
    return out


def _run_generation(run_id: str) -> int:
    return int(run_id.split("-")[0].removeprefix("g"))


def error_on_used(model: np.ndarray, truth: np.ndarray, used: list[int]) -> dict:
    """Mean |model - truth| per component over the gait ids the tests used."""
    e = np.abs(np.asarray(model)[used] - truth[used]).mean(axis=0)
    return {"F": round(float(e[0]), 4), "T": round(float(e[1]), 4), "dH": round(float(e[2]), 4)}


def check_new_run(root: Path) -> None:
    """Refuse to start a run in a folder that holds one (a complete punctuation is there:
    never overwrite it by accident); a command asks before it opens anything."""
    if EvolveDir(root).state.exists():
        raise InputError(f"{root} holds an evolve run: use --resume {root} to continue it, "
                         "or another --out")


def _start(d: EvolveDir, cfg: EvolveConfig) -> tuple[pal.PALState, np.random.Generator, bool]:
    """A fresh state; writes config.json. The bool says no punctuation is done yet."""
    check_new_run(d.root)
    d.root.mkdir(parents=True, exist_ok=True)
    for p in (d.log, d.runs, d.state):
        p.unlink(missing_ok=True)
    append_text(d.runs, "")  # exists even when the observer gives counts, not paths
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


def _resume(d: EvolveDir, model_name: str) -> tuple[pal.PALState, np.random.Generator, bool]:
    """The state after the last complete punctuation, and the run's files made to agree with
    it. The state is a punctuation's commit point (:func:`_persist` writes it first, with the
    punctuation's log record and observed runs): the lines of log.jsonl and runs.jsonl of its
    generation and later ones are replaced by its copy, so a punctuation whose appends a full
    disk or a crash cut short is whole again (a torn last line ignored), and one whose state
    was not written is redone. model.json and turn_cycle.json are written again from the
    state, and a torn last line of observations.jsonl is cut before the resume is noted."""
    if not d.state.exists():
        raise InputError(f"--resume {d.root}: no complete punctuation yet (no state.json); "
                         "start it again without --resume")
    try:
        doc = json.loads(read_text(d.state, "the run's state"))
    except json.JSONDecodeError as e:
        raise InputError(f"{d.state}: not JSON ({e})") from None
    try:
        state, rng = pal.state_from_json(doc)
    except InputError as e:
        raise InputError(f"{d.state}: {e}") from None
    g = state.generation
    last = doc.get("punctuation")  # states saved before it: none, the lines of g are kept
    if last is not None and not (isinstance(last, dict) and isinstance(last.get("log"), dict)
                                 and isinstance(last.get("runs"), list)):
        raise InputError(f"{d.state}: punctuation must hold its log record and runs")

    def kept(path: Path, generation_of: Callable[[dict], int]) -> list[dict]:
        out = []
        for n, r in _numbered(path):
            try:
                gen = generation_of(r)
            except (KeyError, TypeError, ValueError, AttributeError):
                raise InputError(f"{path}:{n}: not a record of an evolve run; cannot "
                                 "resume") from None
            if gen < g or (gen == g and last is None):
                out.append(r)
        return out

    log = kept(d.log, lambda r: int(r["generation"]))
    runs = kept(d.runs, lambda r: _run_generation(r["run_id"]))
    if last is not None:
        log.append(last["log"])
        runs += last["runs"]
    write_atomic(d.log, "".join(json.dumps(r) + "\n" for r in log))
    write_atomic(d.runs, "".join(json.dumps(r) + "\n" for r in runs))
    _write_results(d, state, model_name)
    cut_torn_line(d.observations)
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
    model_name = resolve_table(cfg.model).name
    state, rng, fresh = _resume(d, model_name) if resume else _start(d, cfg)
    pcfg = cfg.pal()
    obs_log = AppendLog(d.observations)
    obs_log({"type": "session", "robot": conn.description, "observer": conn.observer.name,
             "time": time.time()})
    robot = LinkedRobot(conn.robot, conn.observer, conn.placer, cfg.budget, obs_log, cfg.seed,
                        START_POSE)
    robot.progress = progress
    records = _read_jsonl(d.log)
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
                f"{_continue_hint(d)}") from None
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
        try:
            _persist(d, state, rng, rec, robot, timer, model_name, records, pcfg.search)
        except PacError as e:  # a full disk: what is written is whole (pac_host.files)
            raise with_hint(e, _continue_hint(d)) from None
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
    """Write a complete punctuation. The state goes first, whole and on the disk
    (:func:`~pac_host.files.write_atomic`), and carries the punctuation's log record and
    observed runs: it is the punctuation's commit point. Until it is written the previous
    state stands and a resume redoes this punctuation; once it is, the punctuation is
    complete whatever becomes of the writes after it (a full disk, a crash): the runs and the
    log line appended, then the model, the turn cycle and the plots, which a resume restores
    from it (:func:`_resume`). One order and one copy, rather than a transaction over files.
    ``search``: what ran between punctuations (the plots' axis)."""
    from pac_host.plots import coverage_path, learning_progress

    doc = pal.state_to_json(state, rng)
    doc["punctuation"] = {"log": rec, "runs": robot.runs}
    write_atomic(d.state, json.dumps(doc) + "\n")
    runs_log, log = AppendLog(d.runs), AppendLog(d.log)
    for r in robot.runs:
        runs_log(r)
    log(rec)
    records.append(rec)
    _write_results(d, state, model_name)
    best = timer.results[0] if timer.results else None
    if best is not None and best.poses is not None:
        path = fill_gaps(best.poses)  # estimated across the gait cycles not seen, if any
        coverage_path(path, detect_blocks(path), d.path_png,
                      path_title(rec, len(records)), best.figures())
    learning_progress(records, d.progress_png, "PAL on the robot", search)


def _write_results(d: EvolveDir, state: pal.PALState, model_name: str) -> None:
    """model.json and turn_cycle.json of a punctuation's state."""
    table = GaitTable(state.models[0], state.model_effects,
                      f"{model_name} evolved to generation {state.generation}")
    save_table(table, d.model)
    write_atomic(d.turn_cycle, json.dumps({
        "format": "pac-turn-cycle/1", "turn_cycle": format_turn_cycle(state.operational),
        "genes": state.operational.tolist(), "fitness_on_robot": state.operational_fitness,
        "generation": state.generation}, indent=1) + "\n")


def _continue_hint(d: EvolveDir) -> str:
    """How to go on after a run stopped: resume from the last complete punctuation, or, before
    the first, start again."""
    if d.state.exists():
        return (f"`pac-host evolve --resume {d.root}` continues from the last complete "
                "punctuation")
    return f"no punctuation is complete yet: run the same command again (--out {d.root})"
