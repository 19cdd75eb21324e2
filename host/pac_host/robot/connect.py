"""Connect to a robot, its observer and its placer: a real one on a port, or the built-in
emulator (``pac-sim`` in this process, on a real pseudo-terminal, with its tracker feed; opened
by :mod:`pac_host.robot.emulator`, the host's one way into the simulator).

Without a port, the emulator plays the robot and its tracker is the observer; the robot is
placed at each start pose through the tracker socket, as an operator would place a real one.
With a port, the observer is whatever ``--observer`` names and an operator places the robot.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from pac_host.errors import InputError
from pac_host.model.effects import effective_rows
from pac_host.robot.api import EVENT_TIMEOUT_S, StampRobot
from pac_host.robot.emulator import EmulatorOptions, open_emulator
from pac_host.robot.observers import Ask, Observer, TrackerObserver, check_spec, open_observer
from pac_host.robot.placement import OperatorPlacer, Placer, TrackerPlacer
from pac_protocol.link import READY_TIMEOUT_S


@dataclass
class Connection:
    robot: StampRobot
    observer: Observer
    placer: Placer
    description: str
    truth: np.ndarray | None = None  # the emulator's true rows (effects applied), if known
    extra: dict = field(default_factory=dict)


def check_connection(port: str | None, observer_spec: str | None,
                     emulator: EmulatorOptions | None, placer: str = "operator") -> None:
    """Refuse what :func:`connect` would refuse for the options alone, opening nothing (no
    port, emulator, socket or camera): a command checks them before it opens or writes
    anything."""
    if port is None:
        if emulator is None:
            raise InputError("no --port and no emulator options")
    elif observer_spec is None:
        raise InputError("--observer is needed with --port: tracker:HOST:PORT, pipe:PATH "
                         "or manual")
    elif placer == "tracker" and not observer_spec.startswith("tracker:"):
        raise InputError("--placer tracker needs --observer tracker:HOST:PORT")
    if observer_spec is not None:
        check_spec(observer_spec, emulated=port is None)


@contextlib.contextmanager
def connect(
    port: str | None,
    observer_spec: str | None,
    emulator: EmulatorOptions | None,
    ask: Ask | None = None,
    confirm: Callable[[str], None] | None = None,
    manual_mode: str = "figures",
    placer: str = "operator",
) -> Iterator[Connection]:
    """A said-HELLO robot with its observer and placer; everything is closed on exit.

    With a port, ``placer`` is ``operator`` (a person, through ``confirm``) or ``tracker``
    (PLACE lines to the ``tracker:HOST:PORT`` observer: a ``pac-sim`` process's world)."""
    check_connection(port, observer_spec, emulator, placer)
    with contextlib.ExitStack() as stack:
        if port is None:
            yield _emulated(stack, observer_spec, emulator, ask, manual_mode)
            return
        observer = open_observer(observer_spec, ask, manual_mode)
        stack.callback(observer.close)
        place: Placer
        if placer == "tracker":
            host, _, tport = observer_spec.removeprefix("tracker:").rpartition(":")
            place = TrackerPlacer(host, int(tport))
            stack.callback(place.close)
            if isinstance(observer, TrackerObserver):  # pac-sim's tracker: it greets
                observer.await_greeting()
        elif confirm is None:
            raise InputError("a real robot needs an operator to place it at each start pose")
        else:
            place = OperatorPlacer(confirm)
        robot = StampRobot.open(port)
        stack.callback(robot.close)
        yield Connection(robot, observer, place, f"serial port {port}")


def _emulated(stack: contextlib.ExitStack, observer_spec: str | None, o: EmulatorOptions,
              ask: Ask | None, manual_mode: str) -> Connection:
    sim = open_emulator(o)
    stack.callback(sim.close)
    host, tport = sim.tracker.address
    placer = TrackerPlacer(host, tport)
    stack.callback(placer.close)
    observer = open_observer(observer_spec or f"tracker:{host}:{tport}", ask, manual_mode,
                             world=sim.world)
    stack.callback(observer.close)
    if observer_spec is None and isinstance(observer, TrackerObserver):
        # no gait cycle may be published before the tracker sends the observer every pose
        observer.await_greeting()
    sim.start()
    # at real-time factor 0 the emulated Stamp answers within milliseconds: fail fast
    scale = max(o.realtime, 0.25)
    robot = StampRobot.open(sim.path, ready_timeout=READY_TIMEOUT_S * scale,
                            event_timeout=EVENT_TIMEOUT_S * scale)
    stack.callback(robot.close)
    truth = effective_rows(o.table.rows, tuple(o.table.effects) + tuple(o.effects))
    desc = (f"built-in emulator on {sim.path} (true table {o.table.name}, tracker "
            f"{host}:{tport}, noise {o.noise[0]:g} cm / {o.noise[1]:g} deg)")
    return Connection(robot, observer, placer, desc, truth, {"sim": sim})
