"""Putting the robot at a run's start pose: an operator's job, done two ways.

- :class:`OperatorPlacer`: a person carries the robot to the start pose; the caller's
  ``confirm(message)`` callback shows the request and returns when they are done.
- :class:`TrackerPlacer`: the emulator's world is told over its tracker socket
  (``PLACE x y h seed``, answered ``PLACED x y h``, see simulator/README.md), exactly where an
  operator would have put the robot. The seed restarts the tracker's noise for this run, so a
  run's noise depends on the run alone (what makes ``--resume`` reproduce a whole run).

``place`` returns the start pose as observed, or None when only the nominal pose is known.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

from pac_host.robot.observers import LineSource, ObserverError, open_tcp
from pac_protocol.tracker_line import format_place, parse_placed

PLACE_TIMEOUT_S = 5.0


class Placer(Protocol):
    def place(self, run_id: str, pose: Sequence[float], noise_seed: int
              ) -> tuple[float, float, float] | None: ...
    def close(self) -> None: ...


def _fmt(pose: Sequence[float]) -> str:
    return f"({pose[0]:g} cm, {pose[1]:g} cm, heading {pose[2]:g} deg)"


class OperatorPlacer:
    """Asks a person to put the robot at the start pose and waits for them."""

    def __init__(self, confirm: Callable[[str], None]) -> None:
        self.confirm = confirm

    def place(self, run_id: str, pose: Sequence[float], noise_seed: int) -> None:
        self.confirm(f"run {run_id}: place the robot at {_fmt(pose)}, then press Enter")
        return None

    def close(self) -> None:
        pass


class TrackerPlacer:
    """Places the emulated robot through its tracker socket."""

    def __init__(self, host: str, port: int, timeout: float = PLACE_TIMEOUT_S) -> None:
        self.name = f"tracker:{host}:{port}"
        self.timeout = timeout
        self.source: LineSource = open_tcp(host, port, self.name)

    def place(self, run_id: str, pose: Sequence[float], noise_seed: int
              ) -> tuple[float, float, float]:
        self.source.write_line(format_place(pose, noise_seed))
        while True:
            line = self.source.readline(self.timeout)
            if line is None:
                raise ObserverError(f"{self.name}: no answer to PLACE within {self.timeout:g} s")
            parts = line.split()
            if parts[:1] == ["ERROR"]:
                raise ObserverError(f"{self.name}: PLACE refused: {line}")
            try:
                placed = parse_placed(line)
            except ValueError:
                raise ObserverError(f"{self.name}: malformed answer to PLACE: {line!r}") from None
            if placed is not None:
                return placed
            # POSE lines broadcast to every client: not ours to use here

    def close(self) -> None:
        self.source.close()
