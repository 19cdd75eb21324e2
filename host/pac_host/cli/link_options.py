"""Options shared by the commands that drive a robot (evolve, measure): the port, the observer,
the built-in emulator's world, and the operator's prompts."""

from __future__ import annotations

import click

from pac_host import limits
from pac_host.cli.options import Bounded, effects_module_option, load_with_effects
from pac_host.cli.resume import given  # noqa: F401  (re-exported for the commands)
from pac_host.errors import InputError
from pac_host.robot.connect import EmulatorOptions

OPTIONS = [
    click.option("--port", default=None, envvar="PAC_PORT", metavar="PATH|URL",
                 help="Serial port of the robot (or a pyserial URL, or $PAC_PORT). Without it "
                      "the built-in emulator plays the robot."),
    click.option("--observer", "observer_spec", default=None,
                 metavar="tracker:HOST:PORT|pipe:PATH|camera:SOURCE[,OPTS]|manual",
                 help="Where the robot really is: a tracker stream (TCP or named pipe, lines "
                      "'POSE seq gait power_on x y h'), an overhead camera (SOURCE a camera "
                      "index, video or folder with calib=FILE, or sim: the emulator's virtual "
                      "camera; docs/how-to/camera.md) or the operator at a prompt. Default "
                      "with the emulator: its tracker."),
    click.option("--placer", default="operator", show_default=True,
                 type=click.Choice(["operator", "tracker"]),
                 help="With --port: who puts the robot at each start pose: a person (asked, "
                      "then Enter), or the tracker (PLACE lines: a pac-sim process's world)."),
    click.option("--sim-table", default="shifted", show_default=True,
                 metavar="measured|shifted|FILE", help="Emulator: the robot's true gait table."),
    click.option("--sim-effect", "sim_effects", multiple=True, metavar="NAME:P=V,...",
                 help="Emulator: an unmodelled effect of the true robot (repeatable)."),
    effects_module_option(),
    click.option("--sim-noise", default="0.5,1", show_default=True, metavar="POS_CM,HEAD_DEG",
                 help="Emulator: standard deviation of the tracker's noise."),
    click.option("--sim-step-noise", default=None, metavar="CM,DEG|none",
                 help="Emulator: each executed gait cycle's move varies by these standard "
                      "deviations, cm on F and T, deg on dH (seeded per run; not given: the "
                      "--sim-table file's, if any)."),
    click.option("--sim-realtime", default=0.0, show_default=True, type=float,
                 metavar="FACTOR", help="Emulator: wall time per emulated second (1 = real)."),
    click.option("--sim-seed", default=0, show_default=True, type=Bounded(limits.SEED),
                 help="Emulator: seeds its byte faults (tracker noise is seeded per run)."),
    click.option("--drop-prob", default=0.0, type=float,
                 help="Emulator: drop each byte on the line with this probability."),
    click.option("--corrupt-prob", default=0.0, type=float,
                 help="Emulator: corrupt each byte on the line with this probability."),
    click.option("--drop-at", multiple=True, metavar="KIND:N:BYTE",
                 help="Emulator: drop byte BYTE of the N-th frame of type KIND (e.g. "
                      "CYCLE:165:6); repeatable."),
    click.option("--corrupt-at", multiple=True, metavar="KIND:N:BYTE",
                 help="Emulator: flip every bit of byte BYTE of the N-th KIND frame."),
    click.option("--mute-after", default=None, type=int, metavar="N",
                 help="Emulator: stop answering after N gait cycles (tests a dead link)."),
]


def link_options(f):
    for opt in reversed(OPTIONS):
        f = opt(f)
    return f


SIM_NAMES = ("sim_table", "sim_effects", "sim_noise", "sim_step_noise", "sim_realtime",
             "sim_seed", "drop_prob", "corrupt_prob", "drop_at", "corrupt_at", "mute_after")


def emulator_options(o: dict, port: str | None) -> EmulatorOptions | None:
    """EmulatorOptions from the parsed options (popped from ``o``); None with a real port,
    where emulator options make no sense and are refused."""
    if port is not None:
        typed = [n for n in SIM_NAMES if given(n)]
        if typed:
            flag = "--" + typed[0].replace("_", "-")
            flag = "--sim-effect" if flag == "--sim-effects" else flag
            raise InputError(f"{flag} describes the built-in emulator; it does not apply with "
                             "--port")
        return None
    noise_text = o.pop("sim_noise")
    try:
        pos, head = (float(v) for v in noise_text.split(","))
    except ValueError:
        raise InputError(f"--sim-noise: expected POS_CM,HEAD_DEG, got {noise_text!r}") from None
    step_noise = o.pop("sim_step_noise")
    try:
        table = load_with_effects(o.pop("sim_table"), o.pop("sim_effects"), step_noise)
    except InputError as e:  # parse_step_noise names the option --step-noise
        raise InputError(str(e).replace("--step-noise", "--sim-step-noise", 1)) from None
    return EmulatorOptions(
        table=table,
        noise=(pos, head), realtime=o.pop("sim_realtime"), seed=o.pop("sim_seed"),
        drop_prob=o.pop("drop_prob"), corrupt_prob=o.pop("corrupt_prob"),
        drop_at=tuple(o.pop("drop_at")), corrupt_at=tuple(o.pop("corrupt_at")),
        mute_after=o.pop("mute_after"))


def ask(prompt: str) -> str:
    """The operator's answer to a question (manual observer)."""
    return click.prompt(prompt.rstrip(), default="", show_default=False)


def confirm(message: str) -> None:
    """Show the operator what to do and wait for Enter (placing the robot)."""
    click.prompt(message, default="", show_default=False, prompt_suffix=" ")
