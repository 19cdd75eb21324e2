"""The firmware running in the project's PBASIC interpreter (``pac_sim.pbasic``), for the tests:
one gait cycle split into activations, and a scripted host conversation byte for byte."""

from __future__ import annotations

from pac_sim.pbasic import Stamp
from pac_sim.pbasic.peripherals import Pulse

PROGRAMMING_PORT = 16


def const(stamp: Stamp, name: str) -> int:
    return stamp.program.symbols.con_value[name.upper()]


def label(stamp: Stamp, name: str) -> int:
    return stamp.program.symbols.data_addr[name.upper()]


def hip_pins(stamp: Stamp) -> dict[int, int]:
    """pin -> leg of the horizontal (hip) servos."""
    return {const(stamp, f"HIP{leg}"): leg for leg in range(6)}


def lift_pins(stamp: Stamp) -> dict[int, int]:
    """pin -> leg of the vertical (lift) servos."""
    return {const(stamp, f"LIFT{leg}"): leg for leg in range(6)}


def gait_cycle(stamp: Stamp, gait_id: int) -> list[list[Pulse]]:
    """Run the firmware's GaitCycle subroutine for ``gait_id``; its pulses, one list per
    activation (an activation ends with its sixth lift pulse: every lift servo is pulsed once
    in every activation)."""
    lifts = lift_pins(stamp)
    n0 = len(stamp.servo.pulses)
    stamp.call("GaitCycle", gid=gait_id)
    acts: list[list[Pulse]] = [[]]
    seen = 0
    for p in stamp.servo.pulses[n0:]:
        acts[-1].append(p)
        if p.pin in lifts:
            seen += 1
            if seen % len(lifts) == 0:
                acts.append([])
    assert not acts[-1], "pulses after the last activation"
    return acts[:-1]


def converse(stamp: Stamp, script: list[tuple[str, bytes | None]], limit: int = 1000) -> list[int]:
    """Play ``script`` against the firmware: ("S", frame) is what the Stamp must send next,
    ("H", frame) what the host sends at the Stamp's next SERIN, ("H", None) an explicit silence.
    The host stays silent while the Stamp still owes frames. Returns each SERIN's timeout (ms)."""
    got, expected, i, timeouts = bytearray(), bytearray(), 0, []
    for _ in range(limit):
        w = stamp.run_until_serin(10.0)
        got += stamp.output.take(PROGRAMMING_PORT)
        while (i < len(script) and script[i][0] == "S"
               and len(expected) + len(script[i][1]) <= len(got)):
            expected += script[i][1]
            i += 1
        assert bytes(got) == bytes(expected), (
            f"\nStamp sent {bytes(got).hex(' ')}\nexpected   {bytes(expected).hex(' ')}")
        if i == len(script):
            return timeouts
        timeouts.append((w.deadline_us - w.since_us) // 1000)
        who, frame = script[i]
        if who == "H":
            i += 1
            if frame is not None:
                stamp.feed(frame, echo=False)
                continue
        stamp.advance(w.deadline_us - stamp.now_us + 1)
    raise AssertionError("the script did not finish")
