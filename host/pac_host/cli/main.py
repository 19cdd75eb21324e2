"""`pac-host`: the command-line entry point.

Every command module registers itself on :data:`main`; :func:`run` turns the toolkit's typed
errors into one line on stderr and the error's exit code (2 for usage and input errors).
"""

from __future__ import annotations

import sys

import click

from pac_host import __version__
from pac_host.errors import TOOLKIT_ERRORS, exit_code


class _Group(click.Group):
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


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="pac-host")
def main() -> None:
    """Co-evolve the ServoBot's gait model and its mine-sweeping turn cycle.

    A cyclic GA learns a looped sequence of gait cycles on a model of the robot; a model GA with
    partial recombination corrects the model from periodic tests on the robot (punctuated
    anytime learning).

    \b
    Without hardware:  simulate, experiment (the paper's experiment), sweep (experiments over
                       a grid of settings, on a Dask cluster too), evolve (PAL over the
                       serial protocol against the built-in emulator)
    On the robot:      robot hello|status|..., flash, evolve --port, measure
    When model and robot disagree:  diagnose --model TABLE --runs RUNS.jsonl
    Where the robot is:  camera sheets|calibrate|check|serve, --observer camera:...
    """


def _register() -> None:
    from pac_host.cli import (
        camera,
        diagnose,
        evolve,
        experiment,
        flash,
        measure,
        robot,
        simulate,
        sweep,
        table,
    )

    for mod in (table, simulate, experiment, robot, evolve, measure, diagnose, flash, camera,
                sweep):
        mod.register(main)


_register()
