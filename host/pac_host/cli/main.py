"""`pac-host`: the command-line entry point.

The commands load lazily (:data:`COMMANDS`): `pac-host --help` imports none of them. The
group turns the toolkit's typed errors into one line on stderr and the error's exit code (2 for
usage and input errors).
"""

from __future__ import annotations

import os

# Linear algebra on one thread unless the user says otherwise, set before numpy loads (and
# inherited by an experiment's or a sweep's worker processes): the fits' matrices are 32 x 32,
# where BLAS threads only contend, and with --jobs 2 a thread per core per process
# oversubscribed two cores (make test: 6 min 7 s instead of 7 min 51 s)
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import importlib  # noqa: E402
import sys  # noqa: E402

import click  # noqa: E402

from pac_host import __version__  # noqa: E402
from pac_host.errors import TOOLKIT_ERRORS, exit_code, os_error_line  # noqa: E402

# Every command: where it lives ("module:attribute", imported only when the command runs,
# completes its options or shows its own help) and its one-line help, so `pac-host --help` and
# completing a command's name import no command module. tests/host/test_cli_lazy.py checks
# these lines against the commands' own.
COMMANDS: dict[str, tuple[str, str]] = {
    "camera": ("pac_host.cli.camera:camera",
               "An overhead camera with fiducial markers (docs/how-to/camera.md): sheets to print, "
               "plan the cameras of a long area, grab frames, calibrate, check, serve poses, "
               "render a virtual camera's frames; `--observer camera:...` (several cameras "
               "joined by +) for evolve and measure."),
    "diagnose": ("pac_host.cli.diagnose:diagnose_cmd",
                 "Diagnose the gap between a model and observed runs."),
    "evolve": ("pac_host.cli.evolve:evolve_cmd",
               "Co-evolve the model and the turn cycle with tests on the robot (PAL)."),
    "experiment": ("pac_host.cli.experiment:experiment_cmd",
                   "Run PAL from N starting populations with each method."),
    "flash": ("pac_host.cli.flash:flash",
              "Load FIRMWARE (PBASIC source, or an image built by `make firmware`) onto the "
              "BS2."),
    "measure": ("pac_host.cli.measure:measure_cmd",
                "Walk each gait cycle id REPEATS times from a known pose and fit its (F, T, dH)."),
    "optimize": ("pac_host.cli.optimize:optimize_cmd",
                 "Find the best turn cycle on a model: iterated local search with restarts."),
    "robot": ("pac_host.cli.robot:robot_group",
              "Talk to the robot's Stamp (or pac-sim) over a serial port."),
    "simulate": ("pac_host.cli.simulate:simulate_cmd",
                 "Walk a turn cycle from the start pose (45, 30, 90) and score the path."),
    "sweep": ("pac_host.cli.sweep:sweep_cmd",
              "Run `experiment` for every cell of a grid of settings."),
    "table": ("pac_host.cli.table:table_group",
              "Show or export gait tables (the model of how each gait cycle moves the robot)."),
}


def load_command(name: str) -> click.Command:
    """Command ``name`` of :data:`COMMANDS`, its module imported."""
    module, attr = COMMANDS[name][0].split(":")
    return getattr(importlib.import_module(module), attr)


class _Group(click.Group):
    """The commands load lazily (click's lazy group): a command's module is imported when the
    command is looked up to run, not to list the commands or complete their names."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*super().list_commands(ctx), *COMMANDS})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name in self.commands or cmd_name not in COMMANDS:
            return super().get_command(ctx, cmd_name)
        return load_command(cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        names = self.list_commands(ctx)
        limit = formatter.width - 6 - max(map(len, names))
        rows = [(n, (self.commands.get(n) or click.Command(n, help=COMMANDS[n][1]))
                 .get_short_help_str(limit)) for n in names]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def shell_complete(self, ctx: click.Context, incomplete: str) -> list:
        from click.shell_completion import CompletionItem

        names = [CompletionItem(n, help=COMMANDS[n][1]) for n in self.list_commands(ctx)
                 if n in COMMANDS and n.startswith(incomplete)]
        return names + click.Command.shell_complete(self, ctx, incomplete)

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except TOOLKIT_ERRORS as e:
            click.echo(f"pac-host: error: {e}", err=True)
            ctx.exit(exit_code(e))
        except click.UsageError as e:  # a bad option of a command: one line too, exit 2
            where = e.ctx.command_path if e.ctx is not None else ctx.command_path
            click.echo(f"pac-host: error: {e.format_message()} (see '{where} --help')", err=True)
            ctx.exit(2)
        except KeyboardInterrupt:
            click.echo("pac-host: interrupted (work already written is kept)", err=True)
            ctx.exit(130)
        except BrokenPipeError:
            sys.stderr.close()
            ctx.exit(1)
        except (OSError, UnicodeDecodeError) as e:  # the safety net: still one line
            line, code = os_error_line(e)
            click.echo(f"pac-host: error: {line}", err=True)
            ctx.exit(code)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="pac-host")
def main() -> None:
    """Co-evolve the ServoBot's gait model and its mine-sweeping turn cycle.

    A turn-cycle search learns a looped sequence of gait cycles on a model of the robot, and
    periodic tests on the robot correct the model (punctuated anytime learning). By default the
    model is fitted to every observed step and an anytime search spends a budget between
    tests; --profile paper runs the paper's method: a cyclic GA, and a model GA with partial
    recombination (--method full for the paper's comparison).

    \b
    Without hardware:  simulate, optimize (the best turn cycle on a model), experiment (the
                       paper's experiment), sweep (experiments over a grid of settings, on a
                       Dask cluster too), evolve (PAL over the serial protocol against the
                       built-in emulator)
    On the robot:      robot hello|status|..., flash, evolve --port, measure
    When model and robot disagree:  diagnose --model TABLE --runs RUNS.jsonl
    Where the robot is:  camera sheets|calibrate|check|serve, --observer camera:...
    """
