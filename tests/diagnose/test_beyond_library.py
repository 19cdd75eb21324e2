"""Gaps outside the library: the diagnosis says partly_unexplained, names the kind in words and
numbers, and proposes a term that holds on the held-out runs."""

from __future__ import annotations

import re

import numpy as np
import pytest

from pac_host.diagnose import diagnose
from pac_host.diagnose.synth import OUTSIDE, blind_case
from pac_host.model import GaitTable


def _outside(name: str, level: int, seed: int):
    rng = np.random.default_rng([seed, level])
    perturb, truth = OUTSIDE[name][1](rng, level)
    rows, fit, hold = blind_case(rng, [], n_runs=30, n_cycles=50, perturb=perturb)
    d = diagnose(GaitTable(rows), fit, hold, rng, order=sorted(r.run_id for r in fit + hold))
    return d, truth


def _number(text: str, pattern: str) -> float:
    return float(re.search(pattern, text).group(1))


def test_intermittent_stalls_are_named_with_their_share():
    d, truth = _outside("stall", 1, 3)
    assert d.verdict == "partly_unexplained"
    u = d.unexplained
    assert u["kind"] == "intermittent" and "tails" in u["flags"]
    share = _number(u["description"], r"(\d+)% of gait cycles") / 100
    assert share == pytest.approx(truth["p"], abs=0.05)
    assert u["proposal"]["holdout"]["shrink"] > 0.1  # the expected move, replayed


def test_a_periodic_wobble_is_named_with_its_period():
    d, truth = _outside("wobble", 2, 4)
    u = d.unexplained
    assert d.verdict == "partly_unexplained" and u["kind"] == "periodic"
    assert _number(u["description"], r"period about ([\d.]+)") == pytest.approx(
        truth["period"], rel=0.05)
    assert _number(u["description"], r"amplitude about ([\d.]+) deg") == pytest.approx(
        truth["amplitude_deg"], rel=0.3)
    assert u["proposal"]["holdout"]["p_value"] < 0.01


def test_a_payload_change_between_runs_is_a_sudden_change():
    d, truth = _outside("payload", 2, 5)
    u = d.unexplained
    assert d.verdict == "partly_unexplained" and u["kind"] == "sudden_change"
    at = _number(u["description"], r"from (\d+)% of the runs") / 100
    assert at == pytest.approx(truth["from_run_share"], abs=0.08)
    assert _number(u["description"], r"F -(\d+)%") / 100 == pytest.approx(truth["shrink"],
                                                                           abs=0.05)
    h = u["proposal"]["holdout"]
    assert h["rollout_cm_after"] < 0.6 * h["rollout_cm_model"] and h["shrink_over_library"] > 0.5


def test_a_heading_pull_and_a_warm_up_are_described_in_numbers():
    d, truth = _outside("heading_pull", 1, 3)
    u = d.unexplained
    assert d.verdict == "partly_unexplained" and u["kind"] == "heading"
    # described by its peak, either sign first ("by up to -1.0 deg ... most at heading 235
    # deg (and +1.0 at 55)"): the heading of the positive peak
    size = abs(_number(u["description"], r"by up to ([+-]?[\d.]+) deg"))
    m = re.search(r"by up to \+?([\d.]+) deg per gait cycle, most at heading (\d+)",
                  u["description"]) or re.search(r"and \+([\d.]+) at (\d+)", u["description"])
    at = float(m.group(2))
    assert size == pytest.approx(truth["deg_per_cycle"], rel=0.25)
    # dH = c sin(toward - h) is largest 90 degrees before the heading it pulls towards
    assert (at - (truth["toward"] - 90) + 180) % 360 - 180 == pytest.approx(0, abs=20)
    d, truth = _outside("warmup", 1, 3)
    u = d.unexplained
    assert d.verdict == "partly_unexplained" and u["kind"] == "time_since_power_on"
    loss = _number(u["description"], r"-(\d+)% at 0 cycles") / 100
    assert loss == pytest.approx(truth["cold_loss"], abs=0.06)
