"""The PAL loop: the paper's perturbations, the operational rule, reproducibility."""

from __future__ import annotations

import numpy as np

from pac_host.coverage import parse_turn_cycle
from pac_host.learning import pal
from pac_host.model import measured_table, shifted_table

# the paper's method (the default is the whole-table correction: tests/host/test_learning.py)
SMALL = pal.PALConfig(**{**pal.PAPER, "cga_population": 24, "model_population": 16,
                         "generations": 80, "model_generations": 5})


def test_perturbations_follow_the_paper():
    rng = np.random.default_rng(0)
    best = parse_turn_cycle("12:14,3:10,12:3,19:10")
    for _ in range(50):
        a, b = pal.perturbations(best, rng, SMALL)
        assert np.array_equal(a[:, 0], best[:, 0]) and np.array_equal(b[:, 0], best[:, 0])
        nz = best[:, 1] > 0
        assert np.all(np.abs(a[nz, 1] - best[nz, 1]) == 1)  # +-1 on each non-zero count
        assert np.all(a[~nz, 1] == 0)
        assert np.all((b[:, 1] == best[:, 1]) | (b[:, 1] == 50))
    rate = np.mean([np.mean(pal.perturbations(best, rng, SMALL)[1][:, 1] == 50)
                    for _ in range(400)])
    assert 0.2 < rate < 0.3


class _ScriptedRobot:
    """A robot whose results are given: to check the operational-solution rule."""

    def __init__(self, fitnesses):
        self.fitnesses = list(fitnesses)

    def run_tests(self, tests):
        f = self.fitnesses.pop(0)
        return [pal.TestResult(f, f, f, 0)] + [pal.TestResult(1, 1, 1, 0)] * 2


def test_operational_solution_replaced_only_when_better_on_the_robot():
    rng = np.random.default_rng(1)
    state = pal.initial_state(measured_table(), rng, SMALL)
    robot = _ScriptedRobot([5, 3, 8, 8])
    seen = []
    for _ in range(4):
        state, rec = pal.punctuate(state, robot, rng, SMALL)
        seen.append((rec["operational_fitness"], rec["operational_replaced"]))
        state, _ = pal.advance_cga(state, 5, rng, SMALL)
    assert seen == [(5, True), (5, False), (8, True), (8, False)]


def _run(seed, method="partial"):
    cfg = pal.PALConfig(**{**SMALL.__dict__, "method": method})
    rng = np.random.default_rng(seed)
    state = pal.initial_state(measured_table(), rng, cfg)
    records = []
    pal.run(state, pal.SimulatedRobot(shifted_table()), rng, cfg,
            lambda s, r: records.append(r))
    return records


def test_pal_is_reproducible_from_its_seed():
    a, b, c = _run(3), _run(3), _run(4)
    assert a == b
    assert a != c
    assert [r["generation"] for r in a] == [0, 40, 80]


def test_pal_records_say_what_happened():
    rec = _run(5)[0]
    assert len(rec["tests"]) == 3 and len(rec["observed"]) == 3
    assert rec["model_error_after"] <= rec["model_error_before"]
    from pac_host.coverage import expand

    tests = np.stack([parse_turn_cycle(t) for t in rec["tests"]])
    executed = expand(tests, SMALL.budget)[0]
    assert set(rec["used_gait_ids"]) == set(executed.ravel().tolist())
    assert rec["used_gait_ids"][0] == executed[0, 0]


def resumed_and_whole(cfg: pal.PALConfig, seed: int) -> tuple[list, list, dict]:
    """A run saved after its first punctuation and resumed from the file, and the same run
    never stopped: (records resumed, records whole, the saved state)."""
    import json

    robot = pal.SimulatedRobot(shifted_table())
    rng = np.random.default_rng(seed)
    state = pal.initial_state(measured_table(), rng, cfg)
    whole = []
    pal.run(state, robot, rng, cfg, lambda s, r: whole.append(r))

    rng = np.random.default_rng(seed)
    state = pal.initial_state(measured_table(), rng, cfg)
    state, first = pal.punctuate(state, robot, rng, cfg)
    saved = json.loads(json.dumps(pal.state_to_json(state, rng)))  # through a file, as it were
    state, rng = pal.state_from_json(saved)
    state, _ = pal.advance_cga(state, cfg.interval, rng, cfg)
    rest = []
    pal.run(state, robot, rng, cfg, lambda s, r: rest.append(r))
    return [first] + rest, whole, saved


def test_state_round_trip_resumes_bit_for_bit():
    resumed, whole, _ = resumed_and_whole(
        pal.PALConfig(**{**SMALL.__dict__, "generations": 120}), 9)
    assert resumed == whole


def test_anytime_pal_carries_its_search_through_a_saved_state():
    """The default profile's search is part of the state: a run saved after one punctuation
    and resumed from the file is the same run as one never stopped."""
    from dataclasses import replace

    from pac_host.learning import profiles

    cfg = replace(profiles.apply("default", pal.PALConfig(
        cga_population=16, model_population=8, model_generations=2, generations=60,
        interval=20)), search_evaluations=15_000)
    resumed, whole, saved = resumed_and_whole(cfg, 4)
    assert saved["search"]["x"] is not None and saved["search"]["explore"] is not None
    assert resumed == whole
    assert all(r["search"]["explore_evaluations"] == 3_750 for r in whole)
    # the chain's overspend of the first punctuation is saved, owed by the next budget
    assert saved["search"]["overrun"] == max(0, whole[0]["search"]["evaluations"] - 11_250)


def test_step_fitness_needs_observed_paths():
    import pytest

    from pac_host.errors import InputError

    cfg = pal.PALConfig(**{**SMALL.__dict__, "model_fitness": "steps"})
    rng = np.random.default_rng(1)
    state = pal.initial_state(measured_table(), rng, cfg)
    with pytest.raises(InputError, match="needs the robot's observed paths"):
        pal.punctuate(state, _ScriptedRobot([5]), rng, cfg)
