"""The typed robot API: what a host asks of the ServoBot, over the protocol link.

:class:`StampRobot` wraps :class:`pac_protocol.link.StampLink` (which owns framing, READY-led
exchanges and retries) and adds what a run needs: a gait-cycle callback, the power-on count
before a run, a lost DONE recovered through STATUS, and typed errors for a robot that stops
answering or resets mid-run. It never prints.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from pac_host.errors import PacError
from pac_protocol.errors import NoAnswer, StampReset
from pac_protocol.link import READY_TIMEOUT_S, StampLink
from pac_protocol.messages import Boot, Cycle, Done, HelloReply, Reason, State, StatusReply
from pac_protocol.port import open_port

EVENT_TIMEOUT_S = 2.5  # one gait cycle (1.16 s) + the listening window + margin


class RobotSilent(PacError):
    """The robot stopped answering (during a run or a request)."""

    def __init__(self, message: str, cycles: int = 0) -> None:
        super().__init__(message)
        self.cycles = cycles


class RobotReset(PacError):
    """The robot rebooted during a run (power dip, brown-out); its RAM state is gone."""

    def __init__(self, message: str, cycles: int = 0) -> None:
        super().__init__(message)
        self.cycles = cycles


@dataclass
class RunReport:
    """How a RUN or STEP ended: gait cycles done, whether it completed, the reports received
    (a report damaged on the line is lost, so ``reports`` may have gaps in ``done``)."""

    requested: int
    done: int
    completed: bool
    power_on_before: int
    reports: list[Cycle] = field(default_factory=list)

    @property
    def lost_reports(self) -> int:
        return self.done - len(self.reports)


class StampRobot:
    """One session with a ServoBot: HELLO first, then typed commands.

    ``event_timeout``: the longest silence tolerated during a run before asking STATUS; if that
    is not answered either, :class:`RobotSilent` is raised.
    """

    def __init__(self, link: StampLink, event_timeout: float = EVENT_TIMEOUT_S) -> None:
        self.link = link
        self.name = link.name
        self.event_timeout = event_timeout
        self.info: HelloReply | None = None

    @classmethod
    def open(
        cls,
        port: str,
        ready_timeout: float = READY_TIMEOUT_S,
        event_timeout: float = EVENT_TIMEOUT_S,
    ) -> StampRobot:
        """Open ``port`` (a device or any pyserial URL) and say HELLO."""
        ser = open_port(port)
        try:
            robot = cls(StampLink(ser, name=port, ready_timeout=ready_timeout), event_timeout)
            robot.hello()
        except BaseException:
            ser.close()
            raise
        return robot

    def close(self) -> None:
        close = getattr(self.link.port, "close", None)
        if close is not None:
            close()

    def __enter__(self) -> StampRobot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- requests ----------------------------------------------------------------------------

    def hello(self) -> HelloReply:
        self.info = self.link.hello()
        return self.info

    def status(self) -> StatusReply:
        return self.link.status()

    def stop(self) -> None:
        self.link.stop()

    def load(self, genes: Sequence[tuple[int, int]]) -> None:
        """Store a turn cycle: 1..9 (gait id, repetitions) genes."""
        self.link.load([(int(g), int(r)) for g, r in genes])

    def stored(self) -> list[tuple[int, int]]:
        """The turn cycle stored in the robot's EEPROM."""
        count = self.status().count
        return [(r.gait, r.reps) for r in (self.link.read_gene(i) for i in range(count))]

    # ---- runs --------------------------------------------------------------------------------

    def run(self, cycles: int, on_cycle: Callable[[Cycle], None] | None = None) -> RunReport:
        """Run the stored turn cycle for ``cycles`` gait cycles; ``on_cycle`` sees each
        finished gait cycle's report as it arrives. Returns when the robot is idle again."""
        n0 = self.status().power_on
        self.link.run(cycles)
        return self.follow(cycles, n0, on_cycle)

    def step(
        self, gait: int, reps: int, on_cycle: Callable[[Cycle], None] | None = None
    ) -> RunReport:
        """Walk gait cycle ``gait`` ``reps`` times (see :meth:`run`)."""
        n0 = self.status().power_on
        self.link.step(gait, reps)
        return self.follow(reps, n0, on_cycle)

    def follow(
        self, n: int, n0: int = 0, on_cycle: Callable[[Cycle], None] | None = None
    ) -> RunReport:
        """Wait for the run in progress (``n`` gait cycles, started at power-on count ``n0``)
        to end, e.g. after a :meth:`stop`; ``on_cycle`` sees each report."""
        seen: list[Cycle] = []
        try:
            return self._follow(n, n0, on_cycle, seen)
        except KeyboardInterrupt:  # a person wants the robot to stop: tell it, best effort
            with contextlib.suppress(PacError):
                self.stop()
            raise

    def _follow(self, n: int, n0: int, on_cycle: Callable[[Cycle], None] | None,
                seen: list[Cycle]) -> RunReport:
        while True:
            ev = self.link.next_event(self.event_timeout)
            if ev is None:
                st = self._status_during_run(n, seen)
                if st.state == State.IDLE:  # the DONE report was lost on the line
                    return RunReport(n, st.done, st.done >= n, n0, seen)
                continue
            if isinstance(ev, Boot):
                raise RobotReset(
                    f"{self.name}: the robot reset during a run after {self._done(seen)} gait "
                    "cycles (power dip?); its stored turn cycle is kept, the run is lost",
                    self._done(seen),
                )
            if isinstance(ev, Cycle):
                seen.append(ev)
                if on_cycle is not None:
                    on_cycle(ev)
            elif isinstance(ev, Done):
                return RunReport(n, ev.done, ev.reason == Reason.COMPLETED, n0, seen)

    @staticmethod
    def _done(seen: list[Cycle]) -> int:
        return seen[-1].done if seen else 0

    def _status_during_run(self, n: int, seen: list[Cycle]) -> StatusReply:
        try:
            return self.status()
        except (NoAnswer, StampReset) as e:
            raise RobotSilent(
                f"{self.name}: the robot stopped answering during a run of {n} gait cycles, "
                f"after {self._done(seen)} reported ({e})",
                self._done(seen),
            ) from None
