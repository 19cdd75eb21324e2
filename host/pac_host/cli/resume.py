"""Strict ``--resume``: a run goes on with the options it was started with.

A command that resumes saves its options in its folder when a run starts (``experiment``:
OUT/config.json, written by :func:`options_doc` through the library; ``evolve``: its
config.json; ``sweep``: OUT/sweep.json). ``--resume`` then refuses, before writing anything, a
folder that is missing, empty or holds no run of the command (:func:`saved_doc`), and options
typed on the command line that differ from the saved ones, each named (:func:`refuse`); the
others are taken from the saved run, and :func:`took_line` says which.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from pathlib import Path

import click
from click.core import ParameterSource

from pac_host.errors import InputError
from pac_host.files import read_text

# options that say how or where a run runs, not what it computes: neither saved nor compared
EXECUTION = frozenset({"out_dir", "resume", "resume_dir", "jobs", "scheduler",
                       "connect_timeout", "quiet"})


def given(name: str) -> bool:
    """True if the option was typed on the command line (or set by its environment
    variable), not its default."""
    src = click.get_current_context().get_parameter_source(name)
    return src is not None and src.name in ("COMMANDLINE", "ENVIRONMENT")


def jsonable(value):
    """An option's value as JSON keeps it: tuples as lists, paths as text."""
    if isinstance(value, (tuple, list)):
        return [jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def saved_doc(folder: Path, name: str, fmt: str, what: str) -> dict:
    """The saved options document ``folder/name`` of a run to resume (format ``fmt``); one
    line (InputError) if the folder is missing, empty or holds no such run (``what``: "an
    experiment run")."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"--resume {folder}: no such directory; nothing to resume (start a "
                         "run with --out)")
    if not any(folder.iterdir()):
        raise InputError(f"--resume {folder}: the directory is empty (no {name}); nothing to "
                         "resume")
    path = folder / name
    if not path.exists():
        raise InputError(f"--resume {folder}: no {name} there (not {what})")
    text = read_text(path, "the saved run's options")  # undecodable: one line naming it
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not JSON ({e})") from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        raise InputError(f"--resume {folder}: {name} is not a {fmt} file (not {what})")
    return doc


def _param(name: str) -> click.Parameter:
    ctx = click.get_current_context()
    return next(p for p in ctx.command.params if p.name == name)


def _flag(name: str) -> str:
    p = _param(name)
    return p.opts[0] if p.opts else name.upper()


def _is_flag(name: str) -> bool:
    p = _param(name)
    return isinstance(p, click.Option) and p.is_flag


def _value(value) -> str:
    if isinstance(value, list):
        return ",".join(map(str, value)) if value else "(none)"
    return "(unset)" if value is None else str(value)


def show(name: str, value) -> str:
    """``--flag value`` as typed (a boolean flag as itself or its --no- form)."""
    if _is_flag(name):
        p = _param(name)
        return p.opts[0] if value else (p.secondary_opts[0] if p.secondary_opts
                                        else f"no {p.opts[0]}")
    return f"{_flag(name)} {_value(value)}"


def refuse(differ: list[tuple[str, object, object]], out_flag: str = "--out") -> None:
    """One line naming each option typed that differs from the saved run's:
    ``differ`` holds (name, value typed, saved value)."""
    if not differ:
        return
    parts = [f"{show(n, now)} differs from the saved run's "
             f"{show(n, was) if _is_flag(n) else _value(was)}" for n, now, was in differ]
    flags = " and ".join(_flag(n) for n, _, _ in differ)
    raise InputError("; ".join(parts) + f"; resume takes the saved options, drop {flags} or "
                     f"start a new {out_flag}")


def took_line(taken: dict[str, object]) -> str:
    """What a resumed run took from the saved one that this command line would not have
    given (the options left out whose saved value is not the default)."""
    if not taken:
        return "resuming with the saved options (none differs from this command line's)"
    return "resuming with the saved options " + " ".join(show(n, v) for n, v in taken.items())


def options_doc(fmt: str, effective: dict[str, object] | None = None,
                normalise: Callable[[str, object], object] | None = None) -> dict:
    """The command's options as a run saves them: each option's value (but the
    :data:`EXECUTION` ones), the names typed, and ``effective``: the values the run used for
    options whose default is chosen by other options (a profile's, say), which a resume
    compares typed options against."""
    ctx = click.get_current_context()
    norm = normalise or (lambda n, v: v)
    names = [n for n in ctx.params if n not in EXECUTION]
    return {"format": fmt,
            "options": {n: jsonable(norm(n, ctx.params[n])) for n in names},
            "typed": sorted(n for n in names if given(n)),
            "effective": {n: jsonable(v) for n, v in (effective or {}).items()}}


def resumable(folder_param: str, name: str, fmt: str, what: str,
              normalise: Callable[[str, object], object] | None = None,
              out_flag: str = "--out") -> Callable:
    """Decorates a command that saves :func:`options_doc` (as ``name``, format ``fmt``) in
    its ``folder_param`` folder: with ``--resume`` it runs with the saved options instead of
    its defaults, the names typed then marked typed again (so the options a profile
    chooses are chosen the same way), after refusing a folder without such a run and typed
    options that differ, each named, and saying which it took."""
    norm = normalise or (lambda n, v: v)

    def wrap(f: Callable) -> Callable:
        @functools.wraps(f)
        def run(**kw):
            if kw.get("resume"):
                ctx = click.get_current_context()
                doc = saved_doc(kw[folder_param], name, fmt, what)
                kw = _take_saved(ctx, kw, doc, norm, out_flag)
            return f(**kw)
        return run
    return wrap


def _take_saved(ctx: click.Context, kw: dict, doc: dict, norm: Callable,
                out_flag: str) -> dict:
    saved, effective = doc.get("options") or {}, doc.get("effective") or {}
    typed_then = set(doc.get("typed") or ())
    differ, taken = [], {}
    for n, value in saved.items():
        if n not in kw or n in EXECUTION:
            continue
        was = effective.get(n, value)
        now = jsonable(norm(n, kw[n]))
        if given(n):
            if now != was:
                differ.append((n, now, was))
        elif now != value:
            taken[n] = was
    refuse(differ, out_flag)
    click.echo(took_line(taken))
    out = dict(kw)
    for n, value in saved.items():
        if n in kw and n not in EXECUTION:
            p = _param(n)
            out[n] = tuple(value) if isinstance(value, list) and p.multiple else value
            src = ParameterSource.COMMANDLINE if n in typed_then else ParameterSource.DEFAULT
            ctx.set_parameter_source(n, src)
    return out
