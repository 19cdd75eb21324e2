"""The sequence and world effects refitted with the rows
(pac_host.learning.model_fit.refine_effects)."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.diagnose.residuals import batch_of, step_residuals
from pac_host.learning import model_fit
from pac_host.learning.pal import SimulatedRobot
from pac_host.model import measured_table
from pac_host.model.effects import Effect
from pac_host.model.table import GaitTable

TRUE_ALPHA, TRUE_BETA = 0.3, 0.002


def _tests(n_tests: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack([rng.integers(0, 32, size=(n_tests, 9)),
                     rng.integers(1, 10, size=(n_tests, 9))], axis=-1)


def _observed(table: GaitTable, n_tests: int, seed: int, noise: tuple[float, float] = (0, 0)
              ) -> list[model_fit.Observed]:
    rng = np.random.default_rng(seed + 100)
    tests = _tests(n_tests, seed)
    out = []
    for tc, res in zip(tests, SimulatedRobot(table).run_tests(tests), strict=True):
        poses = np.asarray(res.poses, dtype=np.float64).copy()
        poses[:, :2] += rng.normal(0, noise[0], size=(len(poses), 2))
        poses[:, 2] += rng.normal(0, noise[1], size=len(poses))
        ids = model_fit.expand_ids(tc, 200)[: len(poses) - 1]
        out.append(model_fit.Observed(ids, poses))  # each test from power-on, as simulated
    return out


def _truth() -> GaitTable:
    rows = measured_table().rows + np.random.default_rng(5).normal(0, 0.2, size=(32, 3))
    return GaitTable(rows, (Effect("transition", {"alpha": TRUE_ALPHA}),
                            Effect("battery_sag", {"beta": TRUE_BETA})), "test")


def _misfit(post: model_fit.Posterior, obs) -> float:
    batch = batch_of(model_fit._runs(obs))
    return float(np.abs(step_residuals(post.mean, batch, post.effects)).max())


def test_noise_free_steps_give_the_effects_back_and_an_exact_model():
    truth = _truth()
    obs = _observed(truth, 6, seed=1)
    guess = (Effect("transition", {"alpha": 0.31}), Effect("battery_sag", {"beta": 0.0015}))
    rng = np.random.default_rng(0)
    kept = model_fit.correct(measured_table(), obs, rng, selected=guess)
    refit = model_fit.correct(measured_table(), obs, rng, selected=guess, refine=True)
    assert kept.effects == guess  # without refine the selection's values stay
    got = {e.name: e.params for e in refit.effects}
    assert got["transition"]["alpha"] == pytest.approx(TRUE_ALPHA, abs=1e-6)
    assert got["battery_sag"]["beta"] == pytest.approx(TRUE_BETA, abs=1e-8)
    assert refit.selected == guess  # the selection itself is recorded as selected
    # the rows the tests used are exact once the effects are: every step predicted
    assert _misfit(refit, obs) < 1e-4 < 0.01 < _misfit(kept, obs)
    used = refit.evidence > 0
    assert np.abs(refit.mean[used] - truth.rows[used]).max() < 1e-4


def test_noisy_steps_move_the_effects_towards_the_truth_and_never_fit_worse():
    truth = _truth()
    closer = 0
    for seed in range(4):
        obs = _observed(truth, 9, seed=seed, noise=(0.5, 1.0))
        guess = (Effect("transition", {"alpha": 0.2}), Effect("battery_sag", {"beta": 0.0}))
        batch = batch_of(model_fit._runs(obs))
        refit = model_fit.refine_effects(truth.rows, batch, guess)
        assert refit != guess
        alpha = refit[0].params["alpha"]
        closer += abs(alpha - TRUE_ALPHA) < abs(0.2 - TRUE_ALPHA)
        # a minimum: refitting from its own answer moves nothing
        again = model_fit.refine_effects(truth.rows, batch, refit)
        assert again[0].params["alpha"] == pytest.approx(alpha, abs=1e-6)
    assert closer == 4


def test_effects_with_nothing_to_fit_stay_as_they_are():
    truth = _truth()
    batch = batch_of(model_fit._runs(_observed(truth, 2, seed=3)))
    assert model_fit.refine_effects(truth.rows, batch, ()) == ()
    # no change of gait in any run: a transition moves no step, so its value stays
    still = np.full((1, 9, 2), [7, 9])
    res = SimulatedRobot(truth).run_tests(still)[0]
    flat = batch_of(model_fit._runs([model_fit.Observed(
        model_fit.expand_ids(still[0], 200)[: len(res.poses) - 1], np.asarray(res.poses))]))
    alone = (Effect("transition", {"alpha": 0.7}),)
    assert model_fit.refine_effects(truth.rows, flat, alone) == alone


def test_pal_refits_the_effects_with_the_setting_and_not_without():
    """Between selections PAL's correction keeps the selected effects; with refine_effects
    their parameters are fitted again on every run, not otherwise."""
    from dataclasses import replace

    from pac_host.learning import pal

    truth = _truth()
    before = tuple(_observed(truth, 9, seed=2))
    guess = (Effect("transition", {"alpha": 0.25}), Effect("battery_sag", {"beta": 0.0}))
    n = len(before)
    assert not model_fit.structure_due(n + 3, n)  # the selection is not due again
    state = pal.PALState(0, np.zeros((2, 9, 2), dtype=np.int64), measured_table().rows[None],
                         (), np.zeros((9, 2), dtype=np.int64), 0, 0, None, before, None,
                         guess, n)
    tests = _tests(3, seed=4)
    results = SimulatedRobot(truth).run_tests(tests)
    cfg = pal.PALConfig(correction="fit", structure="effects", model_population=2)
    for refine in (False, True):
        _, _, effects, *_ = pal._fit_correction(state, tests, results, np.random.default_rng(0),
                                                replace(cfg, refine_effects=refine))
        alpha = {e.name: e.params for e in effects}["transition"]["alpha"]
        assert alpha == (pytest.approx(TRUE_ALPHA, abs=1e-6) if refine else 0.25)
