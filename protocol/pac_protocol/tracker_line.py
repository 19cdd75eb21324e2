"""The tracker feed's text lines (simulator/README.md): one writer and one parser of each, shared
by the emulator's tracker (``pac_sim.tracker``), the camera's pose server
(``pac-host camera serve``) and the host's observers and placer.

- ``POSE <seq> <gait> <power_on> <x_cm> <y_cm> <h_deg>``: where the robot was seen after the
  gait cycle counted ``power_on`` since power-on (gait -1: a snapshot of the robot at rest).
- ``PLACE <x_cm> <y_cm> <h_deg> [<noise_seed>]``, answered ``PLACED <x_cm> <y_cm> <h_deg>``: a
  client puts the emulated robot at a start pose, as an operator would.
- A stream whose first line starts with :data:`ASK_HEADER` wants to be asked
  ``CYCLE <power_on> <index>`` for each gait cycle, and answers a POSE line or
  ``LOST <power_on> <why>``.

>>> line = format_pose_line(3, 12, 70000 % POWER_ON_MOD, (45.0, 30.5, 90.25))
>>> line
'POSE 3 12 4464 45.000 30.500 90.250'
>>> parse_pose_line(line)
PoseLine(seq=3, gait=12, power_on=4464, pose=(45.0, 30.5, 90.25))
>>> parse_place(format_place((1.5, 2.0, 90.0), 7))
((1.5, 2.0, 90.0), 7)
>>> parse_placed(format_placed((1.5, 2.0, 90.0)))
(1.5, 2.0, 90.0)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from pac_protocol.messages import POWER_ON_MOD  # noqa: F401  (what a line's power_on wraps at)

# A stream that opens with this header wants to be asked: `CYCLE power_on index` for each gait
# cycle (``pac-host camera serve``), and answers a POSE line or `LOST power_on why`.
ASK_HEADER = "# pac-host camera"


@dataclass(frozen=True)
class PoseLine:
    seq: int
    gait: int
    power_on: int
    pose: tuple[float, float, float]


def format_pose_line(seq: int, gait: int, power_on: int, pose: Sequence[float]) -> str:
    """``POSE seq gait power_on x y h`` (millimetre and millidegree resolution, no newline)."""
    x, y, h = pose
    return f"POSE {seq} {gait} {power_on} {x:.3f} {y:.3f} {h:.3f}"


def parse_pose_line(line: str) -> PoseLine:
    """``POSE seq gait power_on x y h``; ValueError otherwise (a pose that is not finite too)."""
    parts = line.split()
    if len(parts) != 7 or parts[0] != "POSE":
        raise ValueError("expected 'POSE seq gait power_on x y h'")
    pose = (float(parts[4]), float(parts[5]), float(parts[6]))
    if not all(math.isfinite(v) for v in pose):
        raise ValueError("pose is not finite")
    return PoseLine(int(parts[1]), int(parts[2]), int(parts[3]), pose)


def format_place(pose: Sequence[float], noise_seed: int) -> str:
    """``PLACE x y h seed``, the pose written exactly (repr), so the world gets the very floats."""
    x, y, h = (float(v) for v in pose)
    return f"PLACE {x!r} {y!r} {h!r} {int(noise_seed)}"


def parse_place(line: str) -> tuple[tuple[float, float, float], int | None]:
    """Parse ``PLACE x y h [seed]`` into the pose and the noise seed (None if not given)."""
    parts = line.split()
    if parts[:1] != ["PLACE"] or len(parts) not in (4, 5):
        raise ValueError(f"expected PLACE x y h [seed], got {line.strip()!r}")
    pose = (float(parts[1]), float(parts[2]), float(parts[3]))
    seed = int(parts[4]) if len(parts) == 5 else None
    if seed is not None and seed < 0:
        raise ValueError(f"noise seed must be >= 0, got {seed}")
    return pose, seed


def format_placed(pose: Sequence[float]) -> str:
    """``PLACED x y h``: the pose the tracker sees the placed robot at."""
    x, y, h = pose
    return f"PLACED {x:.3f} {y:.3f} {h:.3f}"


def parse_placed(line: str) -> tuple[float, float, float] | None:
    """The pose of a ``PLACED x y h`` line; None for a line of another shape; ValueError when
    its numbers are not numbers."""
    parts = line.split()
    if parts[:1] != ["PLACED"] or len(parts) != 4:
        return None
    return float(parts[1]), float(parts[2]), float(parts[3])
