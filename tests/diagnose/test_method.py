"""The diagnosis on blind cases: it names a known effect, rejects effect-free data, finds both
effects of a pair, and says partly_unexplained when the true effect is withheld."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.diagnose import diagnose
from pac_host.diagnose.fit import Problem, fit_effects
from pac_host.diagnose.likelihood import whitener
from pac_host.diagnose.noise import estimate_noise
from pac_host.diagnose.residuals import batch_of
from pac_host.diagnose.synth import blind_case
from pac_host.errors import InputError
from pac_host.model import Effect, GaitTable, measured_table


def _diagnose(effects, seed, library=None, perturb=False):
    rng = np.random.default_rng(seed)
    rows, fit, hold = blind_case(rng, effects, n_runs=30, n_cycles=50, perturb_table=perturb)
    return diagnose(GaitTable(rows), fit, hold, rng, library)


@pytest.mark.parametrize("effect, seed", [
    (Effect("transition", {"alpha": 0.35}), 1),
    (Effect("floor_slope", {"s": 0.4, "theta": 250.0}), 2),
    (Effect("turn_shift", {"k": -1}), 3),
])
def test_finds_a_known_effect(effect, seed):
    d = _diagnose([effect], seed, perturb=seed % 2 == 0)
    assert [e.name for e in d.selected] == [effect.name]
    assert d.verdict == "explained"
    assert d.holdout["shrink"] > 0.6
    lo, hi = d.holdout["shrink_ci"]
    assert lo <= d.holdout["shrink"] <= hi
    assert d.candidates[0]["effect"] == effect.name
    est = d.selected[0].params
    for k, v in effect.params.items():
        if k == "theta":  # a compass direction: compare modulo 360
            assert (est[k] - v + 180) % 360 - 180 == pytest.approx(0, abs=10)
        else:
            assert est[k] == pytest.approx(v, rel=0.1, abs=0.05)


def test_rejects_effect_free_data():
    d = _diagnose([], 4)
    assert d.selected == []
    assert d.verdict == "no_significant_gap"
    assert d.candidates and d.selection.steps[0]["accepted"] is False


def test_finds_both_effects_of_a_pair():
    d = _diagnose([Effect("yaw_bias", {"delta": -0.6}), Effect("battery_sag", {"beta": 3e-4})], 5)
    assert {e.name for e in d.selected} == {"yaw_bias", "battery_sag"}
    assert d.verdict == "explained"


@pytest.mark.parametrize("effect, seed", [
    (Effect("transition", {"alpha": 0.4}), 6),
    (Effect("yaw_bias", {"delta": 0.7}), 7),
])
def test_withheld_effect_is_unexplained_not_misnamed(effect, seed):
    library = [n for n in ("turn_shift", "turn_scale", "stride_scale", "yaw_bias",
                           "lateral_slip", "transition", "battery_sag", "floor_slope")
               if n != effect.name]
    d = _diagnose([effect], seed, library=library)
    assert d.verdict == "partly_unexplained"
    assert effect.name not in [c["effect"] for c in d.candidates]


def test_fit_intervals_cover_the_truth(make_runs):
    true = Effect("lateral_slip", {"gamma": 0.06})
    b = batch_of(make_runs([true], seed=9))
    prob = Problem(measured_table().rows, (), b, whitener(b, estimate_noise(b)))
    fr = fit_effects(prob, ["lateral_slip"])
    lo, hi = fr.intervals["lateral_slip"]["gamma"]
    est = fr.effects[0].params["gamma"]
    assert lo < est < hi
    se = (hi - lo) / (2 * 1.96)
    assert abs(est - 0.06) < 3 * se  # the 95% interval is honest to within sampling
    assert hi - lo < 0.005
    shift = fit_effects(prob, ["turn_shift"])
    assert shift.effects[0].params["k"] == 0  # no shift in these data: k = 0 is best


def test_library_restriction_is_checked():
    rng = np.random.default_rng(0)
    rows, fit, hold = blind_case(rng, [], n_runs=6, n_cycles=20)
    with pytest.raises(InputError, match="unknown effect 'wobble'"):
        diagnose(GaitTable(rows), fit, hold, rng, ["wobble"])


def test_short_runs_are_reported_as_uninformative():
    rng = np.random.default_rng(3)
    rows, fit, hold = blind_case(rng, [Effect("battery_sag", {"beta": 3e-4})], n_runs=4,
                                 n_cycles=6)
    d = diagnose(GaitTable(rows), fit, hold, rng)
    text = " ".join(d.notes)
    assert "too short" in text
    assert not d.informative
    assert "battery_sag" in d.identifiability["invisible"]


def test_effects_already_in_the_model_are_kept_and_not_refitted():
    from pac_host.diagnose import split_runs
    from pac_host.diagnose.synth import world_runs
    from pac_host.search.cga import random_population

    rng = np.random.default_rng(12)
    known = Effect("yaw_bias", {"delta": 0.6})
    rows = measured_table().rows
    varied = random_population(np.random.default_rng(3), 30)  # many gait changes
    runs = world_runs(rows, [known, Effect("transition", {"alpha": 0.4})], varied, 50, rng)
    fit, hold = split_runs(runs, 0.3, rng)
    d = diagnose(GaitTable(rows, (known,)), fit, hold, rng)
    assert [e.name for e in d.selected] == ["transition"]
    assert "yaw_bias" not in [c["effect"] for c in d.candidates]
    assert [e.name for e in d.corrected_table().effects] == ["yaw_bias", "transition"]
    assert d.verdict == "explained"


def test_noise_floor_without_repeated_steps_is_an_upper_bound():
    from pac_host.diagnose.residuals import step_residuals
    from pac_host.diagnose.synth import world_runs

    rng = np.random.default_rng(2)
    alternate = np.array([[[12, 1], [28, 1]] + [[0, 0]] * 7] * 4)  # never 3 same steps in a row
    runs = world_runs(measured_table().rows, [], alternate, 40, rng)
    b = batch_of(runs)
    nf = estimate_noise(b, step_residuals(measured_table().rows, b, []))
    assert nf.method == "residual_rms_upper_bound" and not nf.reliable
    assert 0.5 * 0.9 <= nf.pos_cm < 0.5 * 1.3
    assert 1.0 * 0.9 <= nf.heading_deg < 1.0 * 1.3


def test_an_effect_the_held_out_runs_cannot_show_is_flagged(cycles):
    from pac_host.diagnose import split_runs
    from pac_host.diagnose.synth import world_runs

    rng = np.random.default_rng(12)
    runs = world_runs(measured_table().rows, [Effect("transition", {"alpha": 0.4})],
                      cycles[:30], 50, rng)
    fit, hold = split_runs(runs, 0.3, rng)
    # these turn cycles change gait once in all fitting runs and never in the held-out ones
    assert np.ptp(batch_of(hold).ids, axis=1).max() == 0
    d = diagnose(GaitTable(measured_table().rows), fit, hold, rng)
    assert d.selected == []
    assert not d.informative
    assert any(n.startswith("transition fits the fitting runs") for n in d.notes)
