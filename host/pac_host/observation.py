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


@dataclass(frozen=True)
class Observation:
    """What an observer saw of one run: the poses after each gait cycle (n, 3), or the coverage
    figures the operator counted, or only the final pose; and the pose the robot stood at
    before its first gait cycle, if the observer saw it (``start``: a camera does)."""

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
