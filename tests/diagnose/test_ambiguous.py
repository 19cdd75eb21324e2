"""When two explanations outside the library fit the runs equally, the report says so, names
both with their evidence and proposes the run that would separate them; a clear case is
still named."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.diagnose import diagnose
from pac_host.diagnose.pipeline import split_runs
from pac_host.diagnose.report import summary
from pac_host.diagnose.synth import world_runs
from pac_host.model import GaitTable, measured_table

RIGHT, LEFT, STRAIGHT = 6, 16 + 6, 15


def _right_turns_weaker(i, body, pose, n0, ids, r):
    """Right turns move 25% less and turn 15% less: a weak side, or the play taken up on the
    first cycle after the direction reverses?"""
    hit = ids[:, i] == RIGHT
    return body * np.where(hit[:, None], [0.75, 1.0, 0.85], 1.0)


def test_two_explanations_that_fit_equally_are_both_named_with_a_separating_run():
    # every right turn comes straight after left turns and is followed by a straight cycle:
    # on these runs "a right turn" and "the first cycle after the turn direction reverses"
    # are the same gait cycles
    rng = np.random.default_rng(5)
    cycles = np.array([[(LEFT, int(rng.integers(2, 6))), (RIGHT, 1), (STRAIGHT, 1)] * 3
                       for _ in range(24)])
    runs = world_runs(measured_table().rows, [], cycles, 40, rng, perturb=_right_turns_weaker)
    fit, hold = split_runs(runs, 0.3, rng)
    d = diagnose(GaitTable(measured_table().rows), fit, hold, rng,
                 order=[r.run_id for r in runs])
    u = d.unexplained
    assert d.verdict == "partly_unexplained"
    assert u["kind"] == "ambiguous" and u["kind_verdict"] == "ambiguous"
    assert {"turn", "previous_gait_cycle"} <= set(u["alike"])
    first, second = u["ranking"][0], u["ranking"][1]
    lo, hi = second["behind_leader_interval_95"]
    assert second["alike_leader"] and lo <= 0.0  # the lead is within its uncertainty
    assert first["gain_interval_95"][0] > 0  # both fit: the evidence is real
    sep = u["separating_run"]
    # walking right turns without reversing tells a weak side from backlash
    assert sep is not None and sep["separation_sigma"] > 5
    assert all(g < 15 for g in sep["gait_cycles"])  # right turns only
    text = "\n".join(summary(d))
    assert "ambiguous" in text and "a run that would tell them apart" in text
    assert "turn" in text and "previous_gait_cycle" in text


@pytest.mark.xfail(strict=True, reason="with the whole-run likelihood the weak right side on "
                   "these runs is described as a band of turn strengths (3-9), not the side: a "
                   "known limit of the confined proposals, docs/explanation/diagnosis.md")
def test_a_clear_case_is_still_named():
    # the same weak right side on runs that turn both ways in every order: only "right turns"
    # fits
    rng = np.random.default_rng(6)
    genes = rng.choice([2, 6, 10, 15, 18, 22, 26], size=(24, 9))
    cycles = np.stack([genes, rng.integers(1, 6, size=genes.shape)], axis=-1)
    runs = world_runs(measured_table().rows, [], cycles, 40, rng, perturb=_right_turns_weaker)
    fit, hold = split_runs(runs, 0.3, rng)
    d = diagnose(GaitTable(measured_table().rows), fit, hold, rng,
                 order=[r.run_id for r in runs])
    u = d.unexplained
    assert u["kind"] == "turn" and u["kind_verdict"] == "named"
    assert "on right turns" in u["description"]
    assert u["ranking"][1]["behind_leader_interval_95"][0] > 0  # clearly ahead
    assert u["where"]["component"] == "F"
    assert "turn=right" in [c["context"] for c in u["where"]["contexts"]]
    assert "what is missing (turn)" in "\n".join(summary(d))
