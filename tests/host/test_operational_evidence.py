"""The robot's step noise estimated from observed runs, and the operational turn cycle chosen
on the evidence of all its walks (pac_host.diagnose.noise.estimate_step_noise,
pac_host.learning.operational)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pac_host.coverage import coverage_score, parse_turn_cycle
from pac_host.diagnose.noise import estimate_step_noise
from pac_host.diagnose.runs import Run
from pac_host.learning import model_fit, operational, pal
from pac_host.learning.testing import TestResult
from pac_host.model import measured_table
from pac_host.model.effects import Effect, step_moves
from pac_host.model.kinematics import integrate

START = np.array([45.0, 30.0, 90.0])
TURN_CYCLES = ("12:20,3:10,19:8", "31:15,5:6,22:12", "12:9,31:20,7:5")


def walk(turn_cycle: np.ndarray, step: tuple[float, float], tracker: tuple[float, float],
         rng: np.random.Generator, budget: int = 200, effects=(), n0: int = 0
         ) -> tuple[np.ndarray, np.ndarray]:
    """Gait ids and observed poses of one walk of the measured table (with ``effects``,
    ``n0`` gait cycles after power-on): sd * normal added to each move (cm on F and T, deg on
    dH), then tracker noise on each pose."""
    ids = model_fit.expand_ids(turn_cycle, budget)
    body, world = step_moves(measured_table().rows, ids, effects, n0)
    body = body + rng.standard_normal(body.shape) * np.array([step[0], step[0], step[1]])
    poses = integrate(START, body, world)
    return ids, poses + rng.standard_normal(poses.shape) * np.array([*tracker[:1] * 2,
                                                                    tracker[1]])


def runs(step, tracker, seed: int, n: int = 9, effects=()) -> list[Run]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        ids, poses = walk(parse_turn_cycle(TURN_CYCLES[i % 3]), step, tracker, rng,
                          effects=effects, n0=200 * i)
        out.append(Run(str(i), poses[0], ids, poses[1:], 200 * i))
    return out


def test_the_estimate_recovers_the_step_noise_within_its_interval():
    truth = np.array([0.3, 0.3, 1.0])
    covered = 0
    for seed in range(8):
        fit = estimate_step_noise(runs((0.3, 1.0), (0.2, 0.5), seed))
        covered += bool(((fit.interval[:, 0] <= truth) & (truth <= fit.interval[:, 1])).all())
        assert fit.clear()
        assert np.abs(fit.value - truth).max() < 0.15
        assert fit.to_json()["dH"]["interval"] == [round(float(v), 4) for v in fit.interval[2]]
    assert covered >= 6


def test_a_noise_free_robot_has_no_step_noise_even_through_a_noisy_tracker():
    for seed in range(4):
        exact = estimate_step_noise(runs((0.0, 0.0), (0.0, 0.0), seed))
        assert exact.value.max() < 1e-9 and not exact.clear()
        assert exact.decided().is_zero()
        tracked = estimate_step_noise(runs((0.0, 0.0), (0.2, 0.5), seed))
        assert tracked.value[:2].max() < 0.1 and tracked.value[2] < 0.3
        assert not tracked.clear()


def test_heading_noise_under_a_noisier_tracker_shows_over_whole_loops(monkeypatch):
    """0.15 cm / 0.5 deg of step noise seen through 0.5 cm / 1 deg of tracker noise, three
    punctuations of three walks: within stretches of one gait cycle the step noise is mostly
    lost in the tracker's; summed over whole loops of the turn cycle too it is found, close to
    the truth, more precisely, and clear."""
    clear, clear_steps = 0, 0
    for seed in range(6):
        observed = runs((0.15, 0.5), (0.5, 1.0), seed)
        fit = estimate_step_noise(observed)
        assert abs(fit.value[2] - 0.5) < 0.15, fit.to_json()
        clear += fit.clear()
        with monkeypatch.context() as m:
            m.setattr("pac_host.diagnose.noise.loop_heading_noise", lambda *a: None)
            steps_only = estimate_step_noise(observed)
        clear_steps += steps_only.clear()
        assert fit.var_se[2] < 0.7 * steps_only.var_se[2]
    assert clear == 6 and clear_steps <= 3


def test_a_battery_that_sags_and_a_heading_drift_are_not_step_noise():
    """Moves shrinking over the runs and a constant yaw: every loop turns differently, but
    alike from one loop to the next, so a noise-free robot through a noisy tracker is still
    not noisy."""
    effects = (Effect("battery_sag", {"beta": 0.0008}), Effect("yaw_bias", {"delta": 0.7}))
    for seed in range(4):
        fit = estimate_step_noise(runs((0.0, 0.0), (0.5, 1.0), seed, effects=effects))
        assert not fit.clear() and fit.value[2] < 0.2, fit.to_json()


def test_no_repeated_steps_no_estimate():
    ids = np.array([12, 3] * 10)
    poses = np.zeros((20, 3))
    assert estimate_step_noise([Run("a", np.zeros(3), ids, poses)]) is None


def test_one_lucky_walk_does_not_beat_six_but_a_clear_gap_does():
    est = {"op": operational.estimate([10, 9, 11, 10, 10, 10], 10.0, 20.0, 0.0),
           "lucky": operational.estimate([45], 10.0, 20.0, 0.0)}
    assert est["lucky"].mean < 45  # shrunk toward the model's prediction
    assert operational.decide("op", est, ["lucky"]) == (None, "lucky")
    sure = {**est, "lucky": operational.estimate([45], 10.0, 2.0, 0.0)}
    assert operational.decide("op", sure, ["lucky"]) == ("lucky", None)
    # without noise each walk is exact: the higher walk wins, as the paper's rule
    exact = {"op": operational.estimate([10], 0.0, 0.0, 0.0),
             "b": operational.estimate([11], 0.0, 0.0, 0.0)}
    assert operational.decide("op", exact, ["b"]) == ("b", None)
    assert operational.decide("b", exact, ["op"]) == (None, None)



def test_a_lucky_operational_sweep_is_walked_again_until_fresh_walks_confirm_it():
    """Made operational on three walks that beat the rest, it is the luckiest of its tests:
    while a challenger is not clearly worse it is walked again, up to CONFIRM_WALKS walks, and
    then the two take turns."""
    n = operational.CONFIRM_WALKS

    def est(op_walks: list[int], challenger: float) -> dict:
        return {"op": operational.estimate(op_walks, 24.0, 6.0, 0.0, error_var=4.0),
                "new": operational.estimate([challenger], 24.0, 6.0, 0.0, error_var=4.0)}

    close = est([32, 32, 33], 25.0)
    assert close["op"].mean > close["new"].mean  # no challenger higher ...
    assert operational.decide("op", close, ["new"], operational.TRACKED_Z) == (None, "op")
    confirmed = est([32, 32, 33] + [26] * (n - 3), 25.0)
    # confirmed but still too close to call: now the challenger, known less well, walks again
    assert confirmed["new"].sd > confirmed["op"].sd
    assert operational.decide("op", confirmed, ["new"], operational.TRACKED_Z) == (None, "new")
    clearly_worse = est([32, 32, 33], 2.0)
    assert operational.decide("op", clearly_worse, ["new"], operational.TRACKED_Z) == (None,
                                                                                      None)


class LuckyRobot:
    """Walks every test with step noise; its fitness is 10 on the operational turn cycle and
    45 on any other (each a single lucky walk)."""

    def __init__(self, op: np.ndarray, seed: int) -> None:
        self.op, self.rng = op, np.random.default_rng(seed)

    def run_tests(self, tests: np.ndarray) -> list[TestResult]:
        out = []
        for t in tests:
            _, poses = walk(t, (0.3, 1.0), (0.0, 0.0), self.rng)
            f = 10 if np.array_equal(t, self.op) else 45
            out.append(TestResult(f, f, f, 0, poses))
        return out


def _noisy_state(cfg: pal.PALConfig) -> tuple[pal.PALState, np.ndarray]:
    state = pal.initial_state(measured_table(), np.random.default_rng(0), cfg)
    op = parse_turn_cycle("12:20,3:10,19:8")
    return replace(state, operational=op, operational_score=int(coverage_score(10, 0)),
                   operational_fitness=10,
                   walks={operational.key(op): (10, 9, 11, 10, 10, 10)}), op


@pytest.mark.parametrize("walk_sd, replaced", [(20.0, False), (2.0, True)])
def test_a_single_lucky_walk_replaces_the_operational_turn_cycle_only_on_evidence(
        monkeypatch, walk_sd, replaced):
    """With large walk-to-walk noise one walk of 45 against six of 10 is not enough (a repeat
    is asked for, and the next punctuation tests it); with small noise it is."""
    cfg = pal.PALConfig(cga_population=16, model_population=8, operational_evidence=True)
    state, op = _noisy_state(cfg)

    def model_walks(models, effects, cands, budget, noise, rng):
        assert noise.uniform() is not None and not noise.is_zero()  # the estimated noise
        n = len(cands)
        return np.full(n, 10.0), np.full(n, walk_sd), np.zeros(n)

    monkeypatch.setattr(operational, "model_walks", model_walks)
    # before the model has a track record (it counts as one walk at most); a record of three
    # 45s against its predictions of 10 would rightly hand the decision to the walks
    monkeypatch.setattr(operational, "MIN_TRACK", 10**6)
    new, rec = pal.punctuate(state, LuckyRobot(op, 1), np.random.default_rng(1), cfg)
    assert rec["step_noise"]["clear"]
    assert rec["operational_replaced"] is replaced
    assert all(o["fitness"] == 45 for o in rec["observed"])  # every test a lucky walk
    assert rec["test_walks"] == [1, 1, 1]
    if replaced:
        assert rec["operational"] != operational.key(op)
        assert rec["operational_estimate"]["walks"] == 1
        assert new.repeat is None
    else:
        assert rec["operational"] == operational.key(op) and rec["operational_fitness"] == 10
        est = rec["operational_estimate"]
        assert est["walks"] == 6 and est["interval"][0] < 10 < est["interval"][1]
        assert rec["repeat"] is not None and new.repeat is not None
        tests = operational.with_repeat(pal.choose_tests(new, np.random.default_rng(2), cfg),
                                        new.repeat)
        assert any(np.array_equal(t, new.repeat) for t in tests)


def test_without_the_setting_a_lucky_walk_replaces_it_as_before():
    cfg = pal.PALConfig(cga_population=16, model_population=8)
    state, op = _noisy_state(cfg)
    _, rec = pal.punctuate(state, LuckyRobot(op, 1), np.random.default_rng(1), cfg)
    assert rec["operational_replaced"] and rec["step_noise"]["clear"]
    assert "test_estimates" not in rec
    assert rec["operational_estimate"] == {"mean": 45.0, "interval": None, "walks": 1}


def test_the_walks_and_the_repeat_are_saved_and_resumed():
    cfg = pal.PALConfig(cga_population=16, model_population=8)
    state, op = _noisy_state(cfg)
    state = replace(state, repeat=op)
    rng = np.random.default_rng(5)
    doc = json.loads(json.dumps(pal.state_to_json(state, rng)))
    again, _ = pal.state_from_json(doc)
    assert again.walks == state.walks and np.array_equal(again.repeat, op)
    for k in ("walks", "repeat"):  # a state saved before they existed
        del doc[k]
    old, _ = pal.state_from_json(doc)
    assert old.walks == {} and old.repeat is None


def test_the_model_walked_with_noise_predicts_a_spread_and_without_none():
    from pac_host.model.step_noise import NONE, parse_step_noise

    models = measured_table().rows[None]
    cands = np.stack([parse_turn_cycle(t) for t in TURN_CYCLES])
    mean, sd, spread = operational.model_walks(models, (), cands, 200, parse_step_noise("1,5"),
                                               np.random.default_rng(0), walks=16)
    assert mean.shape == sd.shape == spread.shape == (3,) and (sd > 0).any()
    assert (spread == 0).all()  # one model: no disagreement
    exact, sd0, _ = operational.model_walks(models, (), cands, 200, NONE,
                                            np.random.default_rng(0), walks=4)
    assert (sd0 == 0).all()
    assert exact.tolist() == pal.simulate(models[0], cands, 200).fitness.tolist()


def _track(gap: float, rng: np.random.Generator) -> tuple[dict, dict, dict]:
    """Eight walked turn cycles (three walks each, spread 8) whose means miss the model's
    predictions by about ``gap``."""
    walks, predicted, sd = {}, {}, {}
    for i in range(8):
        p = 15.0 + i
        miss = gap * (1 if i % 2 else -1)
        walks[f"t{i}"] = tuple(p + miss + rng.normal(0, 8, 3))
        predicted[f"t{i}"], sd[f"t{i}"] = p, 8.0
    return walks, predicted, sd


def test_a_race_too_close_to_call_goes_on_past_a_lucky_run_of_walks():
    """Nine walks averaging 27.7 of a sweep whose expectation is 21 (a run of luck a PAL run on
    the noisy shifted robot met) against a challenger of 25 with four walks: neither is
    clearly better, so the one known less well walks again, each fresh walk at its
    expectation, until the better sweep is called. Capped at CONFIRM_WALKS the lucky
    sweep was never walked again and held for good."""
    truth = {"op": 21.0, "new": 25.0}
    walks = {"op": [33, 33, 17, 29, 33, 23, 26, 23, 32], "new": [24, 26, 25, 23]}
    assert len(walks["op"]) > operational.CONFIRM_WALKS
    predicted = {"op": 21.0, "new": 24.0}
    operational_key, walked_op = "op", 0
    for _ in range(60):
        est = {k: operational.estimate(w, predicted[k], 7.3, 0.0, error_var=8.0)
               for k, w in walks.items()}
        chosen, again = operational.decide(operational_key, est, ["new"],
                                           operational.TRACKED_Z)
        if chosen is not None:
            operational_key = chosen
            break
        assert again is not None  # never left undecided while too close to call
        walked_op += again == "op"
        walks[again].append(truth[again])
    assert operational_key == "new" and walked_op > 0


def test_a_model_whose_predictions_hold_decides_and_one_that_misses_does_not():
    """The model's weight is learnt from its track record: predictions that have held let a
    challenger the model expects to cover 6 more replace the operational turn cycle on one
    poor walk; the same walks against a model that has missed by 10 either way leave the
    decision to the walks (the challenger's one walk is worse: kept, and walked again)."""
    rng = np.random.default_rng(3)
    good = operational.model_error_var(*_track(0.0, rng))
    bad = operational.model_error_var(*_track(10.0, rng))
    assert good is not None and bad is not None and good < 10.0 < 60.0 < bad
    assert operational.model_error_var({"a": (1,)}, {"a": 1.0}, {"a": 8.0}) is None

    def decided(error_var):
        est = {"op": operational.estimate([19, 21, 20, 20], 20.0, 8.0, 0.0, error_var),
               "new": operational.estimate([17], 26.0, 8.0, 0.0, error_var)}
        return operational.decide("op", est, ["new"])

    assert decided(good)[0] == "new"
    # kept, and walked again: it has four walks and the challenger is not clearly worse
    assert decided(bad) == (None, "op")
    assert decided(None)[0] is None  # no track record yet: one walk's worth, not enough
