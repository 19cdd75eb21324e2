"""`pac-sim`: run an emulated ServoBot Stamp on a pseudo-terminal until interrupted.

Prints the port path (open it with `pac-host robot ... --port PATH` or any serial terminal at
9600 8N1) and the tracker's address, then serves until Ctrl-C or SIGTERM. With ``--firmware``
the Stamp runs that PBASIC source; a firmware that stops listening ends pac-sim with one line.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import click

from pac_host import limits
from pac_host.errors import TOOLKIT_ERRORS, InputError, exit_code
from pac_host.model import load_with_effects
from pac_host.model.effects_module import load_effects_module
from pac_sim.line import WINDOW_FLOOR_S, Faults
from pac_sim.runner import SimConfig, SimStamp
from pac_sim.targeted import parse_targets


def _floats(text: str, n: int, what: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != n:
        raise InputError(f"{what}: expected {n} comma-separated numbers, got {text!r}")
    return vals


def parse_tracker(text: str) -> tuple[str, int] | None:
    """``HOST:PORT`` (port 0 = pick a free one) or ``off``."""
    if text == "off":
        return None
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or int(port) > 65535:
        raise InputError(f"--tracker: expected HOST:PORT or off, got {text!r}")
    return host or "127.0.0.1", int(port)


def _prob(v: float, name: str) -> float:
    if not 0.0 <= v <= 1.0:
        raise InputError(f"{name} must be in [0, 1], got {v}")
    return v


def build_config(**o: object) -> SimConfig:
    """A SimConfig from the CLI's option values; every problem is one InputError line."""
    if o["realtime"] < 0:
        raise InputError(f"--realtime must be >= 0, got {o['realtime']}")
    x, y, h = _floats(o["start"], 3, "--start")
    pos, head = _floats(o["tracker_noise"], 2, "--tracker-noise")
    if pos < 0 or head < 0:
        raise InputError(f"--tracker-noise must be >= 0, got {o['tracker_noise']!r}")
    try:
        targets = parse_targets(o["drop_at"], o["corrupt_at"])
    except ValueError as e:
        raise InputError(str(e)) from None
    faults = Faults(
        _prob(o["drop_prob"], "--drop-prob"),
        _prob(o["corrupt_prob"], "--corrupt-prob"),
        o["silent"],
        targets,
    )
    return SimConfig(
        factor=o["realtime"],
        echo=o["echo"],
        faults=faults,
        reset_after=o["reset_after"],
        mute_after=o["mute_after"],
        seed=o["seed"],
        eeprom=o["eeprom"],
        table=load_with_effects(o["table_spec"], o["effect_specs"], o["step_noise"]),
        start=(x, y, h),
        tracker_noise=(pos, head),
        tracker=parse_tracker(o["tracker"]),
        protocol_version=o["protocol_version"],
        firmware_version=o["firmware_version"],
        window_floor_s=o["window_floor"],
        firmware=o["firmware"],
        image=o["image"],
    )


def _load_modules(ctx: click.Context, param: click.Parameter, value: tuple[str, ...]) -> None:
    """``--effects-module``: loaded while the options are parsed, before the table is read."""
    try:
        for path in value:
            load_effects_module(path)
    except InputError as e:
        click.echo(f"{ctx.find_root().info_name}: error: {e}", err=True)
        ctx.exit(exit_code(e))


def _report_downloads(stamp: object, seen: int) -> int:
    """One line on stderr for each download session that ended since the last call."""
    sessions = stamp.downloads
    for dl in sessions[seen:]:
        if dl.finished:
            version = dl.firmware_version
            what = ("the ServoBot firmware " + str(version) if version is not None
                    else "a program other than the ServoBot firmware")
            line = f"flashed {dl.packets} packets: {what}"
        elif dl.packets:
            line = f"download abandoned after {dl.packets} packets"
        else:
            line = f"download refused: {dl.failed or 'the host went quiet'}"
        note = getattr(stamp, "flash_note", None)
        click.echo(f"pac-sim: {line}" + (f"; {note}" if note else ""), err=True)
    return len(sessions)


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
# the simulator's own options (a simulator is no client of the host's CLI); the table, effect
# and module are read by the model's loaders, as pac-host's --table and --effect are
@click.option("--table", "table_spec", default="shifted", show_default=True,
              metavar="measured|shifted|FILE",
              help="The robot's true gait table: measured, shifted or a table file.")
@click.option("--effect", "effect_specs", multiple=True, metavar="NAME:P=V,...",
              help="Add an unmodelled effect, e.g. transition:alpha=0.3 (repeatable).")
@click.option("--step-noise", default=None, metavar="CM,DEG|none",
              help="Each executed gait cycle's move varies by these standard deviations, cm "
                   "on F and T, deg on dH (seeded by --seed; not given: the table file's, if "
                   "any; none: no noise).")
@click.option("--effects-module", multiple=True, metavar="FILE.py", is_eager=True,
              expose_value=False, callback=_load_modules,
              help="Python file defining effects with pac_host.model.effects.register_effect "
                   "(repeatable; see docs/reference/effects.md).")
@click.option(
    "--start",
    default="45,30,90",
    show_default=True,
    metavar="X,Y,H",
    help="Start pose: cm, cm, compass degrees.",
)
@click.option(
    "--tracker",
    default="127.0.0.1:0",
    show_default=True,
    metavar="HOST:PORT",
    help="TCP address of the pose feed (port 0 picks one); 'off' for none.",
)
@click.option(
    "--tracker-noise",
    default="0,0",
    show_default=True,
    metavar="POS_CM,HEADING_DEG",
    help="Standard deviation of the tracker's Gaussian noise.",
)
@click.option("--seed", default=0, show_default=True,
              type=click.IntRange(limits.SEED.lo, limits.SEED.hi), help="Seeds noise and faults.")
@click.option(
    "--eeprom",
    type=click.Path(dir_okay=False),
    default=None,
    help="Persist the stored turn cycle in this file (kept across restarts).",
)
@click.option(
    "--echo", is_flag=True, help="Echo every received byte (the pin-16 programming port)."
)
@click.option(
    "--realtime",
    default=1.0,
    show_default=True,
    type=float,
    metavar="FACTOR",
    help="Wall time = emulated time x FACTOR; 0 = as fast as possible.",
)
@click.option(
    "--window-floor",
    default=WINDOW_FLOOR_S,
    show_default=True,
    type=float,
    metavar="SECONDS",
    help="Shortest real listening window between gait cycles.",
)
@click.option("--drop-prob", default=0.0, type=float, help="Drop each byte with this probability.")
@click.option(
    "--corrupt-prob", default=0.0, type=float, help="Corrupt each byte with this probability."
)
@click.option(
    "--drop-at",
    multiple=True,
    metavar="KIND:N:BYTE",
    help="Drop byte BYTE (0-based) of the N-th frame of type KIND (e.g. CYCLE:165:6, "
    "RUN:1:4); repeatable.",
)
@click.option(
    "--corrupt-at",
    multiple=True,
    metavar="KIND:N:BYTE",
    help="Flip every bit of byte BYTE of the N-th frame of type KIND; repeatable.",
)
@click.option(
    "--reset-after",
    default=None,
    type=int,
    metavar="N",
    help="Reset the Stamp once, mid-frame, after N gait cycles.",
)
@click.option(
    "--mute-after",
    default=None,
    type=int,
    metavar="N",
    help="Stop answering after N gait cycles (a pulled cable), mid-run.",
)
@click.option("--silent", is_flag=True, help="Never send a byte (a dead or absent Stamp).")
@click.option(
    "--protocol-version",
    default=1,
    show_default=True,
    type=int,
    help="Protocol version the emulated firmware announces.",
)
@click.option("--firmware-version", default=1, show_default=True, type=int)
@click.option(
    "--firmware",
    type=click.Path(dir_okay=False),
    default=None,
    metavar="SOURCE.bs2",
    help="Run this PBASIC firmware in the interpreter instead of the protocol-level model.",
)
@click.option(
    "--image",
    type=click.Path(dir_okay=False),
    default=None,
    metavar="IMAGE.json",
    help="With --firmware: start from the tokenizer's image of that source (make firmware).",
)
@click.option(
    "--link",
    "link_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Also make a symlink to the port at this path.",
)
def main(link_path: str | None, **opts: object) -> None:
    """Emulate the ServoBot's BASIC Stamp II on a pseudo-terminal, with a simulated world."""
    try:
        sim = SimStamp(build_config(**opts))
    except TOOLKIT_ERRORS as e:
        click.echo(f"pac-sim: error: {e}", err=True)
        sys.exit(exit_code(e))
    if link_path:
        link = Path(link_path)
        if link.is_symlink():
            link.unlink()
        try:
            link.symlink_to(sim.path)
        except OSError as e:
            sim.close()
            click.echo(f"pac-sim: error: cannot create link {link}: {e.strerror}", err=True)
            sys.exit(2)
    click.echo(f"pac-sim: stamp on {sim.path}")
    if sim.tracker is not None:
        host, port = sim.tracker.address
        click.echo(f"pac-sim: tracker on {host}:{port}")
    sys.stdout.flush()
    # The handler only flips a flag: it runs in the main thread between any two bytecodes, so
    # one that took a lock (threading.Event.set) could deadlock on a lock that thread holds.
    terminated: list[int] = []
    signal.signal(signal.SIGTERM, lambda signum, _frame: terminated.append(signum))
    sim.start()
    seen = 0
    try:
        while not terminated and sim.error is None:
            time.sleep(0.1)
            seen = _report_downloads(sim.stamp, seen)
    except KeyboardInterrupt:
        pass
    finally:
        sim.close()
        if link_path and Path(link_path).is_symlink():
            os.unlink(link_path)
    if sim.error is not None:
        click.echo(f"pac-sim: error: {sim.error}", err=True)
        sys.exit(exit_code(sim.error))
    inexact = getattr(sim.stamp, "inexact", 0)
    if inexact:
        click.echo(f"pac-sim: warning: {inexact} gait cycles' thrust matched no table row exactly "
                   "(the affecter rule: 2 x strength thrusts per affected leg)", err=True)
    click.echo(f"pac-sim: stopped after {sim.stamp.cycles_total} gait cycles", err=True)
