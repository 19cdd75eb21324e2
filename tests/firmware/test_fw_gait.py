"""The gait and the affecter, derived by running the firmware's own code.

``firmware/servobot.bs2`` runs in the project's PBASIC interpreter (``pac_sim.pbasic``): its DATA,
its constants and its affecter line as written. The thrust each hip servo really gets is
counted from the pulses (a pulse that moves the leg backward while its foot is down; the
emulator's world counts with the same code, ``pac_sim.thrust``) and
checked against the paper's rule: the affected side's thrusting servos get 2a of their 29
thrust activations (all 29 when 2a >= 29), the other side all 29.
"""

from __future__ import annotations

import pytest
from fw_build import SOURCE
from fw_stamp import const, gait_cycle, hip_pins, label, lift_pins

from pac_sim.pbasic import Stamp
from pac_sim.thrust import ServoMap, ThrustCounter, side_of

ACTIVATIONS = 58
THRUST = 29
TRIPOD_A = (0, 3, 4)
TRIPOD_B = (1, 2, 5)


@pytest.fixture(scope="module")
def stamp() -> Stamp:
    return Stamp.from_file(SOURCE)


def mirror(stamp: Stamp, leg: int, pulse: int) -> int:
    return pulse if side_of(leg) == 0 else const(stamp, "SERVO_MIRROR") - pulse


def back_pulse(stamp: Stamp, leg: int) -> int:
    return mirror(stamp, leg, const(stamp, "HIP_BACK"))


def down_pulse(stamp: Stamp, leg: int) -> int:
    return mirror(stamp, leg, const(stamp, "LIFT_DOWN"))


def lift_of(stamp: Stamp, act) -> dict[int, int]:
    lifts = lift_pins(stamp)
    return {lifts[p.pin]: p.width for p in act if p.pin in lifts}


def thrust_counts(stamp: Stamp, gait_id: int) -> dict[int, int]:
    """Thrust activations per leg in one gait cycle of ``gait_id``, counted by the emulator's
    own rule (``pac_sim.thrust``: the world of ``pac-sim --firmware`` moves by this count)."""
    servo = ServoMap.from_constants(stamp.program.symbols.con_value)
    n0 = len(stamp.servo.pulses)
    stamp.call("GaitCycle", gid=gait_id)
    [cycle] = ThrustCounter(servo).feed(stamp.servo.pulses[n0:])
    return dict(enumerate(cycle.legs))


def test_gait_cycle_has_58_activations_each_driving_12_servos(stamp):
    acts = gait_cycle(stamp, 15)
    assert len(acts) == ACTIVATIONS
    pins = sorted([*hip_pins(stamp), *lift_pins(stamp)])
    for act in acts:
        assert sorted(p.pin for p in act) == pins


def test_cycle_starts_and_ends_at_the_boundary_pose(stamp):
    hips, lifts = hip_pins(stamp), lift_pins(stamp)
    last = gait_cycle(stamp, 15)[-1]
    for p in last:
        if p.pin in hips:
            leg = hips[p.pin]
            end = "HIP_FWD" if leg in TRIPOD_A else "HIP_BACK"
            assert p.width == mirror(stamp, leg, const(stamp, end)), leg
        else:
            assert p.width == down_pulse(stamp, lifts[p.pin])


def test_tripods_alternate(stamp):
    """Legs 0, 3, 4 keep their feet down through the first half while 1, 2, 5 lift; then the
    reverse."""
    acts = gait_cycle(stamp, 15)
    halves = ((acts[:THRUST], TRIPOD_A, TRIPOD_B), (acts[THRUST:], TRIPOD_B, TRIPOD_A))
    for half, down, up in halves:
        lifts = [lift_of(stamp, a) for a in half]
        for leg in down:
            assert all(lf[leg] == down_pulse(stamp, leg) for lf in lifts)
        for leg in up:
            assert any(lf[leg] != down_pulse(stamp, leg) for lf in lifts)


def test_pulses_stay_within_the_servo_limits(stamp):
    hips = hip_pins(stamp)
    legs = {**hips, **lift_pins(stamp)}
    for g in range(32):
        for act in gait_cycle(stamp, g):
            for p in act:
                names = ("HIP_BACK", "HIP_FWD") if p.pin in hips else ("LIFT_DOWN", "LIFT_UP")
                lo, hi = sorted(mirror(stamp, legs[p.pin], const(stamp, n)) for n in names)
                assert lo <= p.width <= hi, (g, p)


@pytest.mark.parametrize("gait_id", range(32))
def test_affecter_thrust_per_side_follows_the_rule(stamp, gait_id):
    side, a = gait_id >> 4, gait_id & 0x0F
    counts = thrust_counts(stamp, gait_id)
    for leg, n in counts.items():
        expected = min(2 * a, THRUST) if side_of(leg) == side else THRUST
        assert n == expected, (gait_id, leg, counts)
    per_side = [sum(n for leg, n in counts.items() if side_of(leg) == s) for s in (0, 1)]
    assert per_side[side] == 3 * min(2 * a, THRUST)
    assert per_side[1 - side] == 3 * THRUST


def test_strength_15_is_the_plain_gait_on_either_side(stamp):
    def widths(g):
        return [[(p.pin, p.width) for p in act] for act in gait_cycle(stamp, g)]

    assert widths(31) == widths(15)


def test_a_changed_affecter_line_is_caught():
    """The rule check is not vacuous: 3 x strength instead of 2 x strength breaks it."""
    src = SOURCE.read_text(encoding="latin-1")
    line = "IF k >= (strength * 2) THEN drag = side + 1"
    assert src.count(line) == 2
    bad = Stamp.from_source(src.replace(line, line.replace("* 2", "* 3")), "mutant.bs2")
    assert thrust_counts(bad, 3)[0] == 9 != min(2 * 3, THRUST)


def test_eeprom_layout_the_host_and_emulator_rely_on(stamp, built):
    """FwInfo at 0 (tag, versions), the turn cycle at TURN_CYCLE_ADDR, the gait after it, and
    the interpreter's DATA equal to the tokenizer's."""
    from pac_host.stamp.image import FW_TAG, TURN_CYCLE_ADDR, TURN_CYCLE_SIZE

    assert label(stamp, "FwInfo") == 0
    assert bytes(stamp.eeprom.mem[: len(FW_TAG)]) == FW_TAG
    assert label(stamp, "TcCount") == TURN_CYCLE_ADDR
    assert label(stamp, "TcGenes") == TURN_CYCLE_ADDR + 1
    assert label(stamp, "GaitA") == TURN_CYCLE_ADDR + TURN_CYCLE_SIZE
    assert label(stamp, "GaitB") - label(stamp, "GaitA") == THRUST * const(stamp, "ACT_BYTES")
    eeprom = bytes.fromhex(built.image["eeprom"])
    used = stamp.program.symbols.data_used
    assert len(used) > ACTIVATIONS * 4
    assert all(stamp.eeprom.mem[a] == eeprom[a] for a in used)
