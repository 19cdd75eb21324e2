"""Recovery above the link: a test whose link broke down mid-way is redone from its start.

The link (:class:`pac_protocol.link.StampLink`) retries a request and resynchronises with
STATUS before it gives up. When it does give up during a test, or the robot resets,
:func:`with_redos` stops the robot, starts a fresh session (HELLO: allowed here, since no
request is pending) and runs the whole test again, up to a bound; only then the error goes up,
as it would have without recovery. :class:`Recovery` counts what happened.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import ClassVar, TypeVar

from pac_host.errors import TOOLKIT_ERRORS, PacError
from pac_host.robot.api import EVENT_TIMEOUT_S, RobotReset, RobotSilent, StampRobot
from pac_protocol.errors import NoAnswer, StampReset
from pac_protocol.link import READY_TIMEOUT_S
from pac_protocol.messages import State

REDOS = 2  # a broken-down test is redone from its start at most this often
IDLE_POLLS = 10  # STATUS asked at most this often for a stopped robot to become idle
# a robot that falls silent mid-run: after the run's silence (the event timeout) the host waits
# one READY timeout for each request of the give-up, STATUS during the run, then the redo's
# STOP and STATUS (a line on which not a byte arrives is not retried: pac_protocol.link)
SILENT_READY_WAITS = 3


def give_up_s(event_timeout: float = EVENT_TIMEOUT_S,
              ready_timeout: float = READY_TIMEOUT_S) -> float:
    """Seconds from the last byte of a robot that falls silent mid-run (switched off, a
    pulled cable) to the error: the one definition the docs state.

    >>> give_up_s()
    8.5
    """
    return event_timeout + SILENT_READY_WAITS * ready_timeout
# the robot's link broke down; an observer's error is not among them: a marker lost from a
# camera's view, or a tracker that stopped, happens again on a redo
BROKEN_LINK = (RobotSilent, RobotReset, NoAnswer, StampReset)

T = TypeVar("T")


@dataclass
class Recovery:
    """What the recovery did: counts by kind, and every event in order."""

    retries: int = 0
    resyncs: int = 0
    redone_tests: int = 0
    implausible_reports: int = 0
    events: list[dict] = field(default_factory=list)

    KINDS: ClassVar[dict[str, str]] = {
        "retry": "retries", "resync": "resyncs", "redo": "redone_tests",
        "implausible_report": "implausible_reports"}

    def note(self, doc: dict) -> None:
        name = self.KINDS.get(doc["type"])
        if name is not None:
            setattr(self, name, getattr(self, name) + 1)
        self.events.append(doc)

    def counts(self) -> dict[str, int]:
        return {k: v for k, v in asdict(self).items() if k != "events"}


def describe_counts(counts: dict[str, int]) -> str:
    """One line for a command's end: what the recovery did."""
    return (f"link recovery: {counts.get('retries', 0)} retries, {counts.get('resyncs', 0)} "
            f"resyncs, {counts.get('redone_tests', 0)} redone tests, "
            f"{counts.get('implausible_reports', 0)} implausible reports dropped")


def restart_session(robot: StampRobot) -> None:
    """After a broken-down test: the robot stopped, idle, and in a fresh session."""
    with contextlib.suppress(NoAnswer):
        robot.stop()  # honoured at the next gait-cycle boundary
    for _ in range(IDLE_POLLS):
        if robot.status().state == State.IDLE:
            break
        robot.link.next_event(robot.event_timeout)
    else:
        raise RobotSilent(f"{robot.name}: the robot does not stop walking")
    robot.hello()


def with_redos(robot: StampRobot, attempt: Callable[[int], T], note: Callable[[dict], None],
               redos: int = REDOS, observer: object = None) -> T:
    """``attempt(k)`` (k = 0, 1, ...: the k-th redo) until it returns; a broken link makes
    it run again after :func:`restart_session` (and the observer's ``forget``, if it has one:
    what it holds of the cut test is stale), at most ``redos`` times. Each redo is passed to
    ``note``. Gives up with the last attempt's error, or the first one's if the robot cannot
    even be restarted (naming both)."""
    for k in range(redos + 1):
        try:
            return attempt(k)
        except BROKEN_LINK as e:
            if k == redos:
                raise
            note({"type": "redo", "attempt": k + 1, "why": f"{type(e).__name__}: {e}"})
            try:
                restart_session(robot)
            except TOOLKIT_ERRORS as again:
                raise PacError(f"{e} (redoing the test: {again})") from None
            forget = getattr(observer, "forget", None)
            if forget is not None:
                forget()
    raise AssertionError("unreachable")
