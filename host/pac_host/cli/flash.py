"""`pac-host flash`: load the firmware onto the robot's BASIC Stamp II."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from pac_host.stamp.flash import flash_robot
from pac_host.stamp.image import load_image

DEFAULT_SOURCE = "firmware/servobot.bs2"


def _progress_printer():
    tty = sys.stderr.isatty()
    state = {"last": ""}

    def show(stage: str, done: int, total: int) -> None:
        if stage == "packet":
            line = f"flash: packet {done}/{total}"
            if tty:
                click.echo("\r" + line, nl=False, err=True)
            state["last"] = line
            return
        if tty and state["last"]:
            click.echo("", err=True)
            state["last"] = ""
        if stage == "retry":
            click.echo(f"flash: the download failed; trying again from the reset "
                       f"({done + 1} of {total})", err=True)
            return
        words = {"reset": "resetting the Stamp", "identify": "identifying the module",
                 "done": f"{total} packets written", "verify": "asking the new firmware HELLO"}
        click.echo(f"flash: {words.get(stage, stage)}", err=True)

    return show


@click.command("flash")
@click.option("--port", required=True, help="Serial port of the Stamp's programming cable.")
@click.argument("firmware", required=False, default=DEFAULT_SOURCE,
                type=click.Path(path_type=Path, dir_okay=False))
@click.option("--no-verify", is_flag=True, help="Skip the HELLO check after the download.")
@click.option("--attempts", default=3, show_default=True, type=click.IntRange(1),
              help="Downloads tried, each from the reset, before giving up.")
def flash(port: str, firmware: Path, no_verify: bool, attempts: int) -> None:
    """Load FIRMWARE (PBASIC source, or an image built by `make firmware`) onto the BS2.

    Uses the BS2's own download protocol: DTR reset, identification, one acknowledged packet per
    EEPROM block; then asks the new firmware HELLO and checks its version.
    """
    image = load_image(firmware)
    out = flash_robot(port, image, verify=not no_verify, progress=_progress_printer(),
                      attempts=attempts)
    r = out.report
    if not r.reset_line:
        click.echo(f"flash: note: {port} has no DTR line, no reset pulse was sent", err=True)
    for why in out.failures:
        click.echo(f"flash: a download tried again had failed: {why}", err=True)
    line = f"flashed {image.origin} to {port}: {r.packets} packets, BS2 interpreter {r.interpreter}"
    if out.running_version is not None:
        line += f", robot reports firmware {out.running_version}"
    if out.failures:
        line += f" (after {len(out.failures)} failed download(s))"
    click.echo(line)


def register(main: click.Group) -> None:
    main.add_command(flash)
