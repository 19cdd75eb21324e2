"""Options choosing where the work runs: local processes or a Dask cluster."""

from __future__ import annotations

import click


def scheduler_options(f):
    """``--scheduler tcp://HOST:8786`` and ``--connect-timeout SECONDS``."""
    f = click.option("--connect-timeout", default=10.0, show_default=True,
                     type=click.FloatRange(0.1, 3600),
                     help="Seconds to wait for the Dask scheduler to answer.")(f)
    return click.option("--scheduler", default=None, metavar="tcp://HOST:8786",
                        help="Run the tasks on this running Dask cluster (results do not "
                             "depend on it); --jobs is then unused.")(f)
