"""The robot side of PAL over the serial link: :class:`LinkedRobot` implements ``pal.Robot``.

For each tested turn cycle: the robot is put at the start pose (by an operator, or by the
emulator's world), the turn cycle is loaded, run for the budget, and observed; the run starts
where the observer saw the robot stand (a camera), else where the placement says, else at the
nominal start pose; the figures come
from the observed path (:func:`pac_host.coverage.coverage_of_poses`) or from the operator's
count. Every observation is appended to the run's log before it is used, so a robot that stops
answering mid-run leaves a log holding everything seen up to then.

A gait cycle the observer could not see (a camera that lost its marker in that window) is a
gap, a NaN pose, not the end of the test: the test's coverage figures are estimated from the
path filled in across its gaps (:func:`pac_host.coverage.gaps.fill_gaps`; the punctuation's
record says ``"gaps": N`` beside them), the model fit uses the steps seen end to end, and the
observed-runs file holds those stretches (each a run of its own, ``part_of`` the test). The
observer decides when too many are lost and stops the test.

A test whose link broke down mid-way (the robot silent or reset, after the link's own retries
and resynchronisations) is redone from its start, at most
``redos`` times: the robot is stopped and said HELLO to again (a fresh session), re-placed (the
operator is asked again, or the emulator is placed), and the test runs again. Every retry,
resync, dropped report and redone test is logged as it happens and counted in
:attr:`LinkedRobot.recovery`.

A punctuation's tests take minutes on a real robot: :attr:`LinkedRobot.progress`, if set, hears
``progress("tests", done, total, run_id)`` as each test starts and ends, and
``progress("gait cycles", done, budget, run_id)`` every :attr:`LinkedRobot.progress_every`
gait cycles walked.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from pac_host.coverage import START_POSE, coverage_of_poses, expand
from pac_host.coverage.gaps import fill_gaps, seen_stretches, unseen
from pac_host.errors import PacError
from pac_host.files import append_text
from pac_host.learning.testing import TestResult
from pac_host.robot.api import StampRobot
from pac_host.robot.observers import Observation, Observer, ObserverError
from pac_host.robot.placement import Placer
from pac_host.robot.recovery import REDOS, Recovery, with_redos
from pac_protocol.messages import Cycle


class AppendLog:
    """A JSON Lines file written one whole line at a time, flushed at once."""

    def __init__(self, path: Path | None) -> None:
        self.path = path

    def __call__(self, doc: dict) -> None:
        if self.path is None:
            return
        append_text(self.path, json.dumps(doc) + "\n")  # a full disk: one line, no half line


def run_seed(base_seed: int, *key: int) -> int:
    """A run's noise seed from the experiment's seed and the run's identity."""
    return int(np.random.SeedSequence([base_seed, *key]).generate_state(1)[0])


def observed_run(run_id: str, start: Sequence[float], gaits: Sequence[int],
                 poses: np.ndarray, n0: int) -> dict:
    """One line of the observed-runs file (DESIGN.md section 4)."""
    return {"run_id": run_id, "start_pose": [float(v) for v in start],
            "gait_cycles": [int(g) for g in gaits],
            "poses": [[float(v) for v in p] for p in poses],
            "cycles_since_power_on": int(n0)}


def observed_runs(run_id: str, start: Sequence[float], gaits: Sequence[int],
                  poses: np.ndarray, n0: int) -> list[dict]:
    """The observed-runs file's lines of one run: the run itself, or, where the observer has
    gaps in it (NaN poses), each stretch seen end to end as a run of its own (``run_id`` and
    ``-c`` its first gait cycle, starting at the pose seen there, ``part_of`` the run)."""
    path = np.vstack([np.asarray(start, dtype=np.float64)[None], np.asarray(poses)])
    if not unseen(path).any():
        return [observed_run(run_id, start, gaits, poses, n0)]
    return [{**observed_run(f"{run_id}-c{a}", path[a], gaits[a:b], path[a + 1:b + 1], n0 + a),
             "part_of": run_id} for a, b in seen_stretches(path)]


# progress(stage, done, total, detail): see the module docstring
Progress = Callable[[str, int, int, str], None]


class LinkedRobot:
    """Runs PAL's tests on a robot behind a :class:`StampRobot`, with a placer and an observer.

    ``label`` names the runs of the next :meth:`run_tests` call (``g40-t1``: generation 40,
    test 1); ``runs`` holds the observed runs of the last call (DESIGN.md 4 format).
    """

    def __init__(self, robot: StampRobot, observer: Observer, placer: Placer,
                 budget: int, log: AppendLog, seed: int = 0,
                 start_pose: Sequence[float] = START_POSE, redos: int = REDOS) -> None:
        self.robot = robot
        self.redos = redos
        self.recovery = Recovery()
        robot.link.on_event = self._link_event
        self.observer = observer
        self.placer = placer
        self.budget = budget
        self.log = log
        self.seed = seed
        self.start_pose = tuple(float(v) for v in start_pose)
        self.generation = 0
        self.runs: list[dict] = []
        self.current_run = ""  # the run in progress (named in errors)
        self.progress: Progress | None = None
        self.progress_every = 10  # gait cycles between progress reports while walking

    def run_tests(self, tests: np.ndarray) -> list[TestResult]:
        self.runs = []
        out = []
        for i, t in enumerate(tests):
            run_id = f"g{self.generation}-t{i}"
            self._report("tests", i, len(tests), run_id)
            out.append(self.run_one(run_id, np.asarray(t), (self.generation, i)))
            self._report("tests", i + 1, len(tests), run_id)
        return out

    def _report(self, stage: str, done: int, total: int, run_id: str) -> None:
        if self.progress is not None:
            self.progress(stage, done, total, run_id)

    def _on_cycle(self, run_id: str, cycle: Cycle) -> None:
        self.observer.on_cycle(cycle.power_on)
        if cycle.done % self.progress_every == 0:
            self._report("gait cycles", cycle.done, self.budget, run_id)

    def take_recovery(self) -> Recovery:
        """The recovery since the last call (one punctuation's), and start counting afresh."""
        rec, self.recovery = self.recovery, Recovery()
        return rec

    def _link_event(self, doc: dict) -> None:
        doc = {**doc, "run_id": self.current_run}
        self.recovery.note(doc)
        self.log(doc)

    def run_one(self, run_id: str, genes: np.ndarray, key: tuple[int, ...]) -> TestResult:
        """Place, load, run the budget, observe, score one turn cycle (9, 2); redo it from its
        start if the link broke down mid-way (module docstring)."""
        self.current_run = run_id
        return with_redos(self.robot, lambda k: self._attempt(run_id, genes, key, k),
                          self._link_event, self.redos, self.observer)

    def _attempt(self, run_id: str, genes: np.ndarray, key: tuple[int, ...], attempt: int
                 ) -> TestResult:
        genes = np.asarray(genes, dtype=np.int64).reshape(-1, 2)
        stored = [(int(g), int(r)) for g, r in genes if r > 0]
        label = f"{run_id} (redone after a link failure, attempt {attempt + 1})" if attempt \
            else run_id
        seen = self.placer.place(label, self.start_pose, run_seed(self.seed, *key))
        start = tuple(seen) if seen is not None else self.start_pose
        self.log({"type": "start", "run_id": run_id, "turn_cycle": stored,
                  "nominal_start": list(self.start_pose), "observed_start": seen,
                  **({"attempt": attempt} if attempt else {})})
        if not stored or self.budget == 0:  # nothing to walk: the robot stays where it is
            poses = np.tile(np.asarray(start), (self.budget, 1))
            return self._result(run_id, start, [], poses, 0, Observation(poses=poses))
        self.robot.load(stored)
        n0 = self.robot.power_on()
        self.observer.begin(run_id, n0, self.log)
        self._report("gait cycles", 0, self.budget, run_id)
        report = self.robot.run(self.budget, lambda c: self._on_cycle(run_id, c), n0)
        obs = self.observer.finish(report.done)
        self.log({"type": "done", "run_id": run_id, "cycles": report.done,
                  "completed": report.completed, "lost_reports": report.lost_reports,
                  "implausible_reports": report.implausible,
                  "power_on_before": report.power_on_before})
        if not report.completed:
            raise PacError(f"run {run_id}: the robot stopped after {report.done} of "
                           f"{self.budget} gait cycles (STOP from elsewhere?)")
        gaits = expand(genes[None], self.budget)[0][0]
        self._check_reports(run_id, gaits, report.reports)
        if obs.start is not None:  # seen by the instrument that sees every later pose
            start = obs.start
        return self._result(run_id, start, gaits, obs.poses, report.power_on_before, obs)

    def _check_reports(self, run_id: str, gaits: np.ndarray, reports: list) -> None:
        for c in reports:
            if not 1 <= c.done <= len(gaits) or gaits[c.done - 1] != c.gait:
                raise PacError(f"run {run_id}: the robot walked gait {c.gait} as gait cycle "
                               f"{c.done}; the loaded turn cycle says otherwise (firmware?)")

    def _result(self, run_id: str, start: Sequence[float], gaits: Sequence[int],
                poses: np.ndarray | None, n0: int, obs: Observation) -> TestResult:
        if obs.figures is not None:
            f = obs.figures
            return TestResult(f["blocks_covered"], f["blocks_covered_once"], f["fitness"],
                              f["repeat_visits"])
        if poses is None or len(poses) != self.budget:
            got = 0 if poses is None else len(poses)
            raise ObserverError(f"observer {self.observer.name}: {got} poses for run {run_id},"
                                f" expected {self.budget}")
        if len(gaits):
            self.runs += observed_runs(run_id, start, gaits, poses, n0)
        path = np.vstack([np.asarray(start, dtype=np.float64)[None], poses])
        gaps = int(unseen(path).sum())
        cov = coverage_of_poses(fill_gaps(path))  # estimated across the gaps, if any
        if gaps:
            self.log({"type": "gaps", "run_id": run_id, "gaps": gaps,
                      "figures": "estimated from the path filled in across the gaps"})
        return TestResult(int(cov.blocks_covered), int(cov.blocks_covered_once),
                          int(cov.fitness), int(cov.repeat_visits), path)
