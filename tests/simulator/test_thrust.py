"""The rule that turns a gait cycle's thrust per leg into the table row the world walks."""

from __future__ import annotations

import pytest

from pac_sim.pbasic.peripherals import Pulse
from pac_sim.thrust import (
    MAX_THRUST,
    ServoMap,
    ThrustCounter,
    side_of,
    thrust_for,
    walked_gait,
)


def legs_for(gait_id: int) -> list[int]:
    """Thrust per leg that the affecter rule prescribes for a gait id."""
    side, a = gait_id >> 4, gait_id & 15
    return [thrust_for(a) if side_of(leg) == side else MAX_THRUST for leg in range(6)]


@pytest.mark.parametrize("gait_id", range(32))
def test_the_rules_thrust_selects_its_own_row(gait_id):
    w = walked_gait(legs_for(gait_id))
    assert w.exact
    assert w.gait == (15 if gait_id & 15 == 15 else gait_id)  # straight carries no side bit


@pytest.mark.parametrize(
    "legs, gait, exact",
    [
        ([9, 29, 9, 29, 9, 29], 4, False),  # odd count 9: no strength gives it; floor(9 / 2) = 4
        ([29, 1, 29, 1, 29, 1], 16, False),  # left side, count 1: strength 0
        ([6, 29, 6, 29, 7, 29], 3, False),  # right legs disagree (mean 6.33)
        ([6, 20, 6, 20, 6, 20], 3, False),  # both sides short: the weaker one turns
        ([29, 28, 29, 28, 29, 28], 30, True),  # left strength 14
        ([0, 29, 0, 29, 0, 29], 0, True),
    ],
)
def test_counts_that_match_no_strength(legs, gait, exact):
    w = walked_gait(legs)
    assert (w.gait, w.exact) == (gait, exact)


def test_counter_counts_backward_moves_with_the_foot_down():
    """Two legs' worth of servos, 3 activations per cycle: leg 0 thrusts twice (foot down,
    moving back), holds once; leg 1 swings forward, foot up, then lowers it (no thrust)."""
    con = {f"HIP{k}": k for k in range(6)} | {f"LIFT{k}": 6 + k for k in range(6)}
    con |= {"HIP_BACK": 600, "HIP_FWD": 900, "LIFT_DOWN": 700, "SERVO_MIRROR": 1500}
    servo = ServoMap.from_constants(con)
    assert servo.back[1] == 900 and servo.down[1] == 800  # left servos are mirrored
    counter = ThrustCounter(servo, activations=3)
    t = 0
    pulses = []
    for hip0, hip1, lift1 in ((850, 850, 850), (800, 800, 850), (800, 750, 800)):
        for pin, width in ((0, hip0), (1, hip1), *((6 + k, 700 if k % 2 == 0 else 800)
                                                    for k in range(6))):
            if pin == 7:
                width = lift1
            pulses.append(Pulse(t, pin, width))
            t += 1000
    [cycle] = counter.feed(pulses)
    assert cycle.legs == (2, 0, 0, 0, 0, 0)
    assert cycle.start_us == 0 and cycle.end_us == t - 1000
