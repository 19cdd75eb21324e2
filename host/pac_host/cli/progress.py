"""Progress of a command's long work, on stderr.

The lower layers report through a callback, ``progress(stage, done, total)``; :class:`Progress`
is that callback for the commands. On a terminal it draws a click progress bar per stage;
through a pipe it writes a plain line per step, e.g.
``experiment: pal 3/8 runs, 0:41 elapsed, ~1:22 left`` (the elapsed time and the estimate are
the stage's); with ``quiet`` it writes nothing.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping
from typing import IO

import click


def quiet_option(f):
    """``--quiet``: no progress lines or bars on stderr."""
    return click.option("--quiet", is_flag=True,
                        help="Print no progress on stderr (results are printed as before).")(f)


def clock_text(seconds: float) -> str:
    """``H:MM:SS`` or ``M:SS``."""
    s = max(0, round(seconds))
    h, rest = divmod(s, 3600)
    return f"{h}:{rest // 60:02d}:{rest % 60:02d}" if h else f"{rest // 60}:{rest % 60:02d}"


class Progress:
    """The ``progress(stage, done, total)`` callback of a command.

    ``units`` names what a stage counts (``{"pal": "runs"}``). ``minor`` stages are steps
    within another stage's step (the gait cycles of a test): through a pipe a line of theirs
    comes only when no line has for ``minor_every`` seconds; on a terminal they show as the
    current bar's item. ``detail`` (a call's fourth argument) is shown after the line. The
    estimate of what is left counts the steps done since the stage's first call (a resumed
    run's earlier steps took no time here)."""

    def __init__(self, command: str, quiet: bool = False, units: Mapping[str, str] = {},
                 minor: tuple[str, ...] = (), minor_every: float = 10.0,
                 stream: IO[str] | None = None, tty: bool | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.command = command
        self.quiet = quiet
        self.units = dict(units)
        self.minor = minor
        self.minor_every = minor_every
        self.stream = stream if stream is not None else sys.stderr
        self.tty = tty if tty is not None else self.stream.isatty()
        self.clock = clock
        self._started: dict[str, tuple[float, int]] = {}  # stage -> (when, done) first heard
        self._last_line = clock()
        self._bar = None
        self._bar_stage = ""

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __call__(self, stage: str, done: int, total: int, detail: str = "") -> None:
        if self.quiet:
            return
        now = self.clock()
        if done == 0 or stage not in self._started:  # a stage (re)starting: time it from here
            self._started[stage] = (now, done)
        start, first = self._started[stage]
        if self.tty:
            self._draw(stage, done, total, detail)
            return
        if stage in self.minor and now - self._last_line < self.minor_every:
            return
        self._last_line = now
        click.echo(self.line(stage, done, total, now - start, detail, done - first),
                   file=self.stream)

    def line(self, stage: str, done: int, total: int, elapsed: float, detail: str = "",
             timed: int | None = None) -> str:
        """``command: stage done/total units, elapsed, ~left``: the estimate, once a step is
        done, is the time per step of the ``timed`` steps (default ``done``) that took
        ``elapsed``, times the steps left.

        >>> Progress("experiment").line("pal", 3, 8, 41.0)
        'experiment: pal 3/8, 0:41 elapsed, ~1:08 left'
        """
        timed = done if timed is None else timed
        unit = f" {self.units[stage]}" if stage in self.units else ""
        text = f"{self.command}: {stage} {done}/{total}{unit}, {clock_text(elapsed)} elapsed"
        if timed > 0 and done < total:
            text += f", ~{clock_text(elapsed / timed * (total - done))} left"
        return text + (f" ({detail})" if detail else "")

    def _draw(self, stage: str, done: int, total: int, detail: str) -> None:
        if stage in self.minor:
            if self._bar is not None:
                self._bar.update(0, f"{stage} {done}/{total} {self.units.get(stage, '')}"
                                 .rstrip())
            return
        if self._bar is None or self._bar_stage != stage:
            self.close()
            unit = f" ({self.units[stage]})" if stage in self.units else ""
            self._bar = click.progressbar(length=max(total, 1), label=f"{self.command}: "
                                          f"{stage}{unit}", file=self.stream, show_pos=True,
                                          show_eta=True, item_show_func=lambda x: x)
            self._bar.__enter__()
            self._bar_stage = stage
        self._bar.update(done - self._bar.pos, detail or None)
        if done >= total:
            self.close()

    def close(self) -> None:
        """Finish the bar on screen, if one is drawn."""
        if self._bar is not None:
            self._bar.__exit__(None, None, None)
            self._bar = None
