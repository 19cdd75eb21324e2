"""What every observer reports, whatever it watches the robot with: the types shared by the
robot floor's observers (:mod:`pac_host.robot.observers`) and the overhead camera's
(:mod:`pac_host.camera.observer`), so that neither package imports the other to agree on them.

An observer follows one run at a time: :meth:`Observer.begin` before it, :meth:`Observer.on_cycle`
when the robot reports a finished gait cycle, :meth:`Observer.finish` when it has stopped. Every
observation is handed to the ``record`` callback (the run's log) before it is returned or used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pac_host.errors import PacError

Record = Callable[[dict], None]
Ask = Callable[[str], str]


class ObserverError(PacError):
    """An observer gave no usable observation (malformed line, closed stream, silence)."""


MAX_LOST = 0.25  # a test may miss up to this share of its gait cycles' poses (gaps), no more
LOST_GRACE = 32  # gait cycles: before so many, a burst of lost ones is not yet too many


def too_many_lost(lost: int, cycles: int, fraction: float = MAX_LOST,
                  final: bool = False) -> bool:
    """Whether ``lost`` unseen gait cycles (gaps in the path) among the ``cycles`` walked so
    far are too many for the test to go on: more than ``fraction`` of them at the test's end
    (``final``), and while it walks more than ``fraction`` of at least :data:`LOST_GRACE`
    (a camera gone blind stops the test early, a burst at its start does not).

    >>> too_many_lost(8, 10), too_many_lost(9, 10), too_many_lost(3, 10, final=True)
    (False, True, True)
    """
    return lost > fraction * (cycles if final else max(cycles, LOST_GRACE))


@dataclass(frozen=True)
class Observation:
    """What an observer saw of one run: the poses after each gait cycle (n, 3; a row of NaN
    for a gait cycle it could not see), or the coverage figures the operator counted, or only
    the final pose; and the pose the robot stood at before its first gait cycle, if the
    observer saw it (``start``: a camera does)."""

    poses: np.ndarray | None = None
    figures: dict | None = None
    final_pose: tuple[float, float, float] | None = None
    start: tuple[float, float, float] | None = None


class Observer(Protocol):
    name: str

    def begin(self, run_id: str, power_on_before: int, record: Record) -> None: ...
    def on_cycle(self, power_on: int) -> None: ...
    def finish(self, cycles: int) -> Observation: ...
    def close(self) -> None: ...
