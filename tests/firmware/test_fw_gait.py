"""The gait and the affecter, derived by executing the firmware's own gait-cycle code.

The source's DATA, constants and the affecter line are read as written (fw_pbasic executes
the GaitCycle subroutine); the thrust each hip servo really gets is counted from the pulses
and checked against the paper's rule: the affected side's thrusting servos get 2a of their 29
thrust activations (all 29 when 2a >= 29), the other side all 29.
"""

from __future__ import annotations

import pytest
from fw_build import SOURCE
from fw_pbasic import Program

ACTIVATIONS = 58
THRUST = 29
TRIPOD_A = (0, 3, 4)
TRIPOD_B = (1, 2, 5)


@pytest.fixture(scope="module")
def prog() -> Program:
    return Program(SOURCE.read_text(encoding="latin-1"))


def side_of(leg: int) -> int:
    """0 right, 1 left: even legs are on the right (the firmware's leg numbering)."""
    return leg % 2


def pins(prog: Program) -> tuple[dict[int, int], dict[int, int]]:
    hip = {prog.consts[f"HIP{n}"]: n for n in range(6)}
    lift = {prog.consts[f"LIFT{n}"]: n for n in range(6)}
    return hip, lift


def back_pulse(prog: Program, leg: int) -> int:
    c = prog.consts
    return c["HIP_BACK"] if side_of(leg) == 0 else c["SERVO_MIRROR"] - c["HIP_BACK"]


def down_pulse(prog: Program, leg: int) -> int:
    c = prog.consts
    return c["LIFT_DOWN"] if side_of(leg) == 0 else c["SERVO_MIRROR"] - c["LIFT_DOWN"]


def thrust_counts(prog: Program, gait_id: int) -> dict[int, int]:
    """Thrust activations per leg in one gait cycle of ``gait_id``, starting from the cycle
    boundary pose: a hip pulse that moves the leg backward while its foot is down."""
    hip, lift = pins(prog)
    last = {}
    for pin, width in prog.gait_cycle(15)[-1].pulses:  # the boundary pose of the plain gait
        if pin in hip:
            last[hip[pin]] = width
    counts = dict.fromkeys(range(6), 0)
    for act in prog.gait_cycle(gait_id):
        lifts = {lift[p]: w for p, w in act.pulses if p in lift}
        for pin, width in act.pulses:
            if pin not in hip:
                continue
            leg = hip[pin]
            b = back_pulse(prog, leg)
            if lifts[leg] == down_pulse(prog, leg) and abs(width - b) < abs(last[leg] - b):
                counts[leg] += 1
            last[leg] = width
    return counts


def test_gait_cycle_has_58_activations_each_driving_12_servos(prog):
    acts = prog.gait_cycle(15)
    assert len(acts) == ACTIVATIONS
    hip, lift = pins(prog)
    for act in acts:
        assert sorted(p for p, _ in act.pulses) == sorted([*hip, *lift])


def test_cycle_starts_and_ends_at_the_boundary_pose(prog):
    c = prog.consts
    hip, lift = pins(prog)
    last = dict(prog.gait_cycle(15)[-1].pulses)
    for leg in range(6):
        hip_w, lift_w = last[[p for p, n in hip.items() if n == leg][0]], None
        lift_w = last[[p for p, n in lift.items() if n == leg][0]]
        forward = c["HIP_FWD"] if side_of(leg) == 0 else c["SERVO_MIRROR"] - c["HIP_FWD"]
        assert hip_w == (forward if leg in TRIPOD_A else back_pulse(prog, leg)), leg
        assert lift_w == down_pulse(prog, leg), leg


def test_tripods_alternate(prog):
    """Legs 0, 3, 4 thrust in the first half, 1, 2, 5 in the second, 29 activations each."""
    hip, lift = pins(prog)
    acts = prog.gait_cycle(15)
    for half, thrusting in ((acts[:THRUST], TRIPOD_A), (acts[THRUST:], TRIPOD_B)):
        for act in half:
            lifts = {lift[p]: w for p, w in act.pulses if p in lift}
            for leg in thrusting:
                assert lifts[leg] == down_pulse(prog, leg)
        # the repositioning tripod is lifted at some point of its half
        other = TRIPOD_B if thrusting == TRIPOD_A else TRIPOD_A
        for leg in other:
            assert any(
                dict((lift[p], w) for p, w in a.pulses if p in lift)[leg] != down_pulse(prog, leg)
                for a in half
            )


def test_pulses_stay_within_the_servo_limits(prog):
    c = prog.consts
    lo_h, hi_h = sorted((c["HIP_BACK"], c["HIP_FWD"]))
    lo_v, hi_v = sorted((c["LIFT_DOWN"], c["LIFT_UP"]))
    m = c["SERVO_MIRROR"]
    hip, lift = pins(prog)
    for g in range(32):
        for act in prog.gait_cycle(g):
            for pin, w in act.pulses:
                leg = hip.get(pin, lift.get(pin))
                lo, hi = (lo_h, hi_h) if pin in hip else (lo_v, hi_v)
                if side_of(leg):
                    lo, hi = m - hi, m - lo
                assert lo <= w <= hi, (g, pin, w)


@pytest.mark.parametrize("gait_id", range(32))
def test_affecter_thrust_per_side_follows_the_rule(prog, gait_id):
    side, a = gait_id >> 4, gait_id & 0x0F
    counts = thrust_counts(prog, gait_id)
    for leg, n in counts.items():
        expected = min(2 * a, THRUST) if side_of(leg) == side else THRUST
        assert n == expected, (gait_id, leg, counts)
    per_side = [sum(n for leg, n in counts.items() if side_of(leg) == s) for s in (0, 1)]
    assert per_side[side] == 3 * min(2 * a, THRUST)
    assert per_side[1 - side] == 3 * THRUST


def test_strength_15_is_the_plain_gait_and_0_gives_no_thrust(prog):
    plain = prog.gait_cycle(15)
    assert [a.pulses for a in prog.gait_cycle(31)] == [a.pulses for a in plain]
    for g in (0, 16):
        counts = thrust_counts(prog, g)
        assert all(n == 0 for leg, n in counts.items() if side_of(leg) == g >> 4)


def test_data_reader_matches_the_tokenized_eeprom(prog, built):
    """The test's reading of DATA is the tokenizer's: every defined byte agrees."""
    eeprom = bytes.fromhex(built.image["eeprom"])
    assert prog.data, "no DATA parsed"
    for addr, value in prog.data.items():
        assert eeprom[addr] == value, addr
    assert prog.labels["GAITB"] - prog.labels["GAITA"] == THRUST * prog.consts["ACT_BYTES"]


def test_eeprom_layout_the_host_and_emulator_rely_on(prog):
    """FwInfo at 0 (tag, versions) and the turn cycle at TURN_CYCLE_ADDR, as the source says."""
    from pac_host.stamp_image import FW_TAG, TURN_CYCLE_ADDR, TURN_CYCLE_SIZE

    assert prog.labels["FWINFO"] == 0
    assert bytes(prog.data[a] for a in range(len(FW_TAG))) == FW_TAG
    assert prog.labels["TCCOUNT"] == TURN_CYCLE_ADDR
    assert prog.labels["TCGENES"] == TURN_CYCLE_ADDR + 1
    assert prog.labels["GAITA"] == TURN_CYCLE_ADDR + TURN_CYCLE_SIZE
