"""The typed robot API: what a host asks of the ServoBot, over the protocol link.

:class:`StampRobot` wraps :class:`pac_protocol.link.StampLink` (which owns framing, READY-led
exchanges and retries) and adds what a run needs: a gait-cycle callback, the power-on count
before a run, a lost DONE recovered through STATUS, and typed errors for a robot that stops
answering or resets mid-run. It never prints.

The check value is one byte, so a damaged frame passes it about once in 256; and a frame that
lost a byte equal to A5 passes it every time, because the next frame's sync byte takes the
lost byte's place in the sum. Such a frame is well formed but false. So nothing that moves the
host's count of the robot's progress is taken on the check alone: a CYCLE report is used only if
its ``done`` follows the last one within the run and its power-on count agrees with the run's
start (``power_on - done = n0``), a DONE only if its count fits the run, and the power-on count a
run starts from is read twice (two STATUS replies that agree). A report that fails is dropped
(as if lost on the line) and counted.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from pac_host.errors import TOOLKIT_ERRORS, PacError
from pac_protocol.errors import NoAnswer, StampReset
from pac_protocol.link import READY_TIMEOUT_S, StampLink
from pac_protocol.messages import (
    POWER_ON_MOD,
    Boot,
    Cycle,
    Done,
    HelloReply,
    Reason,
    State,
    StatusReply,
)
from pac_protocol.port import open_port

EVENT_TIMEOUT_S = 2.5  # one gait cycle (1.16 s) + the listening window + margin
AGREEING_READS = 6  # STATUS replies asked, at most, for two that agree


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
    implausible: int = 0  # well-formed reports that contradicted the run (dropped)

    @property
    def lost_reports(self) -> int:
        return self.done - len(self.reports)


class StampRobot:
    """One session with a ServoBot: HELLO first, then typed commands.

    ``event_timeout``: the longest silence tolerated during a run (since the last byte heard)
    before asking STATUS; if that is not answered either, :class:`RobotSilent` is raised.
    """

    def __init__(self, link: StampLink, event_timeout: float = EVENT_TIMEOUT_S) -> None:
        self.link = link
        self.name = link.name
        self.event_timeout = event_timeout
        self.info: HelloReply | None = None
        self.implausible = 0  # reports dropped since the session began

    def _event(self, doc: dict) -> None:
        """A recovery event for the caller's log (the link's ``on_event``)."""
        if self.link.on_event is not None:
            self.link.on_event(doc)

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

    def agreed_status(self) -> StatusReply:
        """STATUS until two replies in a row agree (a false reply is one in a few hundred
        damaged frames; two equal ones are the Stamp's). Only for an idle robot."""
        prev = self.status()
        for _ in range(AGREEING_READS - 1):
            st = self.status()
            if st == prev:
                return st
            self._event({"type": "disagreeing_status", "first": prev.describe(),
                         "second": st.describe()})
            prev = st
        raise NoAnswer(f"{self.name}: {AGREEING_READS} STATUS replies, no two in a row agree "
                       "(the line damages most frames)")

    def power_on(self) -> int:
        """Gait cycles since power-on, as two agreeing STATUS replies say (idle robot)."""
        return self.agreed_status().power_on

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

    def run(self, cycles: int, on_cycle: Callable[[Cycle], None] | None = None,
            n0: int | None = None) -> RunReport:
        """Run the stored turn cycle for ``cycles`` gait cycles; ``on_cycle`` sees each
        finished gait cycle's report as it arrives. Returns when the robot is idle again.
        ``n0``: the power-on count before the run, if the caller has read it already
        (:meth:`power_on`)."""
        n0 = self.power_on() if n0 is None else n0
        self.link.run(cycles)
        return self.follow(cycles, n0, on_cycle)

    def step(
        self, gait: int, reps: int, on_cycle: Callable[[Cycle], None] | None = None,
        n0: int | None = None,
    ) -> RunReport:
        """Walk gait cycle ``gait`` ``reps`` times (see :meth:`run`)."""
        n0 = self.power_on() if n0 is None else n0
        self.link.step(gait, reps)
        return self.follow(reps, n0, on_cycle)

    def follow(
        self, n: int, n0: int | None = None, on_cycle: Callable[[Cycle], None] | None = None
    ) -> RunReport:
        """Wait for the run in progress (``n`` gait cycles, started at power-on count ``n0``;
        None: unknown, the reports' power-on counts are not checked) to end, e.g. after a
        :meth:`stop`; ``on_cycle`` sees each report."""
        seen: list[Cycle] = []
        try:
            return self._follow(n, n0, on_cycle, seen)
        except KeyboardInterrupt:  # a person wants the robot to stop: tell it, best effort
            with contextlib.suppress(*TOOLKIT_ERRORS):
                self.stop()
            raise

    def _follow(self, n: int, n0: int | None, on_cycle: Callable[[Cycle], None] | None,
                seen: list[Cycle]) -> RunReport:
        dropped = 0
        misfit: StatusReply | None = None
        while True:
            # a silence counts from the last byte heard, not from when the last report was
            # handled (an observer may take a while over it)
            ev = self.link.next_event(self.event_timeout, since=self.link.last_heard)
            if ev is None:
                st = self._status_during_run(n, seen)
                if st.state != State.IDLE:
                    continue
                if self._fits(st.done, st.power_on, n, n0, seen):
                    # the DONE report was lost on the line
                    return RunReport(n, st.done, st.done >= n, n0 or 0, seen, dropped)
                if st == misfit:  # twice the same: the Stamp's, not a false frame
                    raise RobotReset(
                        f"{self.name}: the robot is idle after {self._done(seen)} reported gait "
                        f"cycles but its counts do not fit the run ({st.describe()}): it reset "
                        "and its BOOT report was lost", self._done(seen))
                misfit = st
                continue
            if isinstance(ev, Boot):
                raise RobotReset(
                    f"{self.name}: the robot reset during a run after {self._done(seen)} gait "
                    "cycles (power dip?); its stored turn cycle is kept, the run is lost",
                    self._done(seen),
                )
            if isinstance(ev, Cycle):
                if not self._fits(ev.done, ev.power_on, n, n0, seen) or ev.done == self._done(
                        seen):
                    dropped += self._implausible(ev.describe(), n, n0, seen)
                    continue
                seen.append(ev)
                if on_cycle is not None:
                    on_cycle(ev)
            elif isinstance(ev, Done):
                whole = ev.reason == Reason.COMPLETED
                if (whole and ev.done != n) or not self._done(seen) <= ev.done <= n:
                    dropped += self._implausible(ev.describe(), n, n0, seen)
                    continue
                return RunReport(n, ev.done, whole, n0 or 0, seen, dropped)

    @staticmethod
    def _fits(done: int, power_on: int, n: int, n0: int | None, seen: list[Cycle]) -> bool:
        """A count the robot reported agrees with the run: no fewer gait cycles than already
        reported, no more than asked, and as many since the run's start as since power-on."""
        last = seen[-1].done if seen else 0
        return last <= done <= n and (n0 is None or (power_on - done - n0) % POWER_ON_MOD == 0)

    def _implausible(self, what: str, n: int, n0: int | None, seen: list[Cycle]) -> int:
        self.implausible += 1
        self._event({"type": "implausible_report", "report": what, "run_cycles": n,
                     "power_on_before": n0, "last_done": self._done(seen)})
        return 1

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
