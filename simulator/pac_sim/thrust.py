"""From a servo trace to the gait cycle the robot really walked.

With ``--firmware`` the world does not take the gait id the firmware meant: it counts, from the
recorded PULSOUTs, the thrust activations each hip servo received in a gait cycle, and picks
the table row with that thrust, so an affecter bug in the firmware moves the robot wrongly.

- **Activation**: one servo refresh; it ends with the pulse that completes a round of the six
  lift servos (each lift servo is pulsed once per activation). 58 activations make a gait cycle.
- **Thrust activation** of a leg: its hip servo gets a pulse that moves the leg backward (nearer
  the full-back width than its previous pulse) while the activation's lift pulse holds its foot
  down. A hip that gets no pulse goes limp and drags: no thrust. Before the first pulse a hip is
  taken to be full forward (the gait cycle's boundary pose has the thrusting tripod there).
- **Row**: per side, the mean count c of its three legs. The side with less thrust is the
  affected side (side bit 0 = right legs = right turn; a tie is side 0); its strength is the a
  with min(2a, 29) = c, i.e. 15 when c >= 29, else floor(c / 2). A cycle is *exact* when the
  three legs of each side agree, the other side has its full 29 and c is min(2a, 29) for some a;
  otherwise (an odd count, legs that disagree, both sides short) the row is still chosen by the
  rule above and the cycle is reported as not exact. Full thrust on both sides is strength 15
  of side 0 (id 15): pulses carry no side bit for a straight gait cycle.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from pac_host.errors import InputError
from pac_sim.pbasic.peripherals import Pulse

LEGS = 6  # even legs are on the right (side 0), odd legs on the left (side 1)
ACTIVATIONS = 58
MAX_THRUST = 29  # thrust activations of a leg in an unaffected gait cycle
STRAIGHT = 15
NEEDED = (
    *(f"HIP{leg}" for leg in range(LEGS)),
    *(f"LIFT{leg}" for leg in range(LEGS)),
    "HIP_BACK",
    "HIP_FWD",
    "LIFT_DOWN",
    "SERVO_MIRROR",
)


def side_of(leg: int) -> int:
    return leg % 2


@dataclass(frozen=True)
class ServoMap:
    """Where the servos are and what their pulses mean, per leg (left servos are mirrored)."""

    hip: tuple[int, ...]  # hip servo pin of each leg
    lift: tuple[int, ...]  # lift servo pin of each leg
    back: tuple[int, ...]  # hip width with the leg full back
    fwd: tuple[int, ...]  # hip width with the leg full forward
    down: tuple[int, ...]  # lift width with the foot on the ground

    @classmethod
    def from_constants(cls, con: Mapping[str, int], name: str = "the firmware") -> ServoMap:
        """From the firmware's CONs HIP0-5, LIFT0-5, HIP_BACK, HIP_FWD, LIFT_DOWN, SERVO_MIRROR
        (right-side widths; a left servo gets SERVO_MIRROR - width)."""
        missing = [n for n in NEEDED if n not in con]
        if missing:
            raise InputError(f"{name} lacks CON {', '.join(missing)}: the emulator reads the "
                             "servo pins and pulse widths from them")

        def per_leg(key: str) -> tuple[int, ...]:
            v = con[key]
            return tuple(v if side_of(leg) == 0 else con["SERVO_MIRROR"] - v for leg in range(LEGS))

        return cls(
            tuple(con[f"HIP{leg}"] for leg in range(LEGS)),
            tuple(con[f"LIFT{leg}"] for leg in range(LEGS)),
            per_leg("HIP_BACK"),
            per_leg("HIP_FWD"),
            per_leg("LIFT_DOWN"),
        )


@dataclass(frozen=True)
class CycleThrust:
    """Thrust activations per leg in one gait cycle, and when its pulses began and ended."""

    legs: tuple[int, ...]
    start_us: int
    end_us: int


class ThrustCounter:
    """Fed the servo trace in time order; returns a :class:`CycleThrust` per gait cycle."""

    def __init__(self, servo: ServoMap, activations: int = ACTIVATIONS) -> None:
        self.servo = servo
        self.activations = activations
        self._hip = {pin: leg for leg, pin in enumerate(servo.hip)}
        self._lift = {pin: leg for leg, pin in enumerate(servo.lift)}
        self.last = list(servo.fwd)  # last commanded hip width per leg
        self.restart()

    def restart(self) -> None:
        """Forget a gait cycle in progress (the Stamp was reset); the servos stay where they are."""
        self._act: list[Pulse] = []
        self._lifts: dict[int, int] = {}
        self._nlift = 0
        self._done = 0
        self._counts = [0] * LEGS
        self._start: int | None = None

    def feed(self, pulses: Iterable[Pulse]) -> list[CycleThrust]:
        out = []
        for p in pulses:
            if self._start is None:
                self._start = p.t_us
            self._act.append(p)
            leg = self._lift.get(p.pin)
            if leg is None:
                continue
            self._lifts[leg] = p.width
            self._nlift += 1
            if self._nlift < LEGS:
                continue
            self._activation()
            self._done += 1
            if self._done == self.activations:
                out.append(CycleThrust(tuple(self._counts), self._start, p.t_us))
                self.restart()
        return out

    def _activation(self) -> None:
        s = self.servo
        for p in self._act:
            leg = self._hip.get(p.pin)
            if leg is None:
                continue
            b = s.back[leg]
            if self._lifts.get(leg) == s.down[leg] and abs(p.width - b) < abs(self.last[leg] - b):
                self._counts[leg] += 1
            self.last[leg] = p.width
        self._act, self._lifts, self._nlift = [], {}, 0


@dataclass(frozen=True)
class WalkedCycle:
    """The table row a gait cycle's thrust selects (see the module text for the rule)."""

    thrust: tuple[int, ...]  # per leg
    side_thrust: tuple[float, float]  # mean per side: right, left
    gait: int
    exact: bool


def thrust_for(strength: int) -> int:
    """The affecter rule: thrust activations of each affected leg at a strength 0..15."""
    return min(2 * strength, MAX_THRUST)


def walked_gait(thrust: Sequence[int]) -> WalkedCycle:
    """The gait id whose affecter rule gives this thrust per leg."""
    sides = [[thrust[leg] for leg in range(LEGS) if side_of(leg) == s] for s in (0, 1)]
    mean = (sum(sides[0]) / len(sides[0]), sum(sides[1]) / len(sides[1]))
    side = 0 if mean[0] <= mean[1] else 1
    c = mean[side]
    strength = STRAIGHT if c >= MAX_THRUST else int(c) // 2
    exact = (
        all(len(set(v)) == 1 for v in sides)
        and mean[1 - side] == MAX_THRUST
        and c == thrust_for(strength)
    )
    return WalkedCycle(tuple(thrust), mean, side << 4 | strength, exact)
