"""`pac-host robot ...`: talk to the ServoBot's Stamp (or `pac-sim`) over a serial port.

Every command opens the port with DTR low (DTR resets a Stamp on its programming port), starts
the session with HELLO (checking the protocol version), then does one thing. Problems are one
line: a bad port exits 2, a silent device or a protocol version mismatch exits 1.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import click

from pac_host.errors import InputError
from pac_host.limits import MAX_GAIT_CYCLES
from pac_host.robot.api import RunReport, StampRobot
from pac_protocol.link import READY_TIMEOUT_S, check_genes
from pac_protocol.messages import MAX_GAIT, Cycle, State


def _port_options(f):
    f = click.option(
        "--timeout",
        default=READY_TIMEOUT_S,
        show_default=True,
        type=float,
        help="Seconds to wait for the Stamp to say it is listening.",
    )(f)
    return click.option(
        "--port",
        required=True,
        envvar="PAC_PORT",
        metavar="PATH",
        help="Serial port of the Stamp or of pac-sim (or $PAC_PORT).",
    )(f)


@contextlib.contextmanager
def session(port: str, timeout: float) -> Iterator[StampRobot]:
    """An open port and a robot that has said HELLO."""
    with StampRobot.open(port, ready_timeout=timeout) as robot:
        yield robot


def _positive(value: int, name: str, hi: int = MAX_GAIT_CYCLES) -> int:
    if not 1 <= value <= hi:
        raise InputError(f"{name} must be 1..{hi}, got {value}")
    return value


def parse_genes(text: str) -> list[tuple[int, int]]:
    """``GAIT:REPS,GAIT:REPS,...`` -> [(gait, reps), ...], validated as a storable turn cycle."""
    genes = []
    for part in text.split(","):
        g, sep, r = part.partition(":")
        if not sep or not g.strip().isdigit() or not r.strip().isdigit():
            raise InputError(f"turn cycle: expected GAIT:REPS,... got {part!r}")
        genes.append((int(g), int(r)))
    check_genes(genes)
    return genes


def _walk(robot: StampRobot, total: int, start) -> None:
    """Start a run with ``start(on_cycle)``, print each gait cycle until it ends; Ctrl-C sends
    STOP and waits for the Stamp to halt."""

    def show(c: Cycle) -> None:
        click.echo(f"gait cycle {c.done}/{total}: gait {c.gait} (since power-on {c.power_on})")

    try:
        rep: RunReport = start(show)
    except KeyboardInterrupt:
        robot.stop()
        rep = robot.follow(total, on_cycle=show)
    how = "completed" if rep.completed else "stopped"
    click.echo(f"done: {how} after {rep.done} gait cycles")


def register(main: click.Group) -> None:
    @main.group()
    def robot() -> None:
        """Talk to the robot's Stamp (or pac-sim) over a serial port."""

    @robot.command()
    @_port_options
    def hello(port: str, timeout: float) -> None:
        """Check the Stamp answers and speaks this protocol version."""
        with session(port, timeout) as robot:
            r = robot.info
        click.echo(
            f"{port}: protocol {r.protocol}, firmware {r.firmware}, up to {r.max_genes} genes"
        )

    @robot.command()
    @_port_options
    def status(port: str, timeout: float) -> None:
        """What the Stamp is doing and what it has stored."""
        with session(port, timeout) as robot:
            s = robot.status()
            genes = robot.stored()
        stored = ",".join(f"{g}:{r}" for g, r in genes) or "none"
        click.echo(
            f"state {State(s.state).name.lower()}, gait cycles done {s.done}, since power-on "
            f"{s.power_on}, turn cycle {stored}"
        )

    @robot.command()
    @_port_options
    @click.argument("gait", type=int)
    @click.argument("reps", type=int)
    def step(port: str, timeout: float, gait: int, reps: int) -> None:
        """Walk GAIT (0..31) REPS times, printing each gait cycle (Ctrl-C stops)."""
        if not 0 <= gait <= MAX_GAIT:
            raise InputError(f"gait id must be 0..{MAX_GAIT}, got {gait}")
        _positive(reps, "repetitions")
        with session(port, timeout) as robot:
            _walk(robot, reps, lambda show: robot.step(gait, reps, show))

    @robot.command()
    @_port_options
    @click.argument("genes")
    def load(port: str, timeout: float, genes: str) -> None:
        """Store a turn cycle GAIT:REPS,... (1..9 genes) in the Stamp's EEPROM."""
        tc = parse_genes(genes)
        with session(port, timeout) as robot:
            robot.load(tc)
        click.echo(f"stored {len(tc)} genes")

    @robot.command()
    @_port_options
    @click.argument("cycles", type=int)
    def run(port: str, timeout: float, cycles: int) -> None:
        """Run the stored turn cycle for CYCLES gait cycles (Ctrl-C stops)."""
        _positive(cycles, "gait cycles")
        with session(port, timeout) as robot:
            _walk(robot, cycles, lambda show: robot.run(cycles, show))

    @robot.command()
    @_port_options
    def stop(port: str, timeout: float) -> None:
        """Stop a run at the next gait-cycle boundary."""
        with session(port, timeout) as robot:
            robot.stop()
        click.echo("stop acknowledged")


def _robot_group() -> click.Group:
    holder = click.Group()
    register(holder)
    return holder.commands["robot"]


#: the `robot` group on its own, as `pac-host` loads it (pac_host.cli.main.COMMANDS)
robot_group = _robot_group()
