"""A sweep cell's settings, mapped onto :class:`~pac_host.experiments.experiment.ExperimentConfig`.

The mapping is generic: every field of the config, nested ones included, is a setting, named by
its dotted path (``pal.cga.bit_mutation_rate``) or, where the name is unambiguous, by the field's
own name (``budget`` is ``pal.budget``: the shallowest field of that name wins; ``population``
exists twice at the same depth, so it needs its path). A field added to the config is sweepable
without a change here; values are checked against the field's type. Besides the config, a cell
names its tables: ``actual`` and ``model`` (``measured``, ``shifted`` or a table file) and
``effects`` (a list of ``name:param=value,...`` added to the actual robot), and its ``profile``
(:mod:`pac_host.learning.profiles`: ``paper``, ``default``, or ``none``, the configuration's
own defaults), applied under the cell's other settings. Unless a cell sets ``methods``, it
compares :func:`~pac_host.experiments.experiment.default_methods` of its PAL configuration.

>>> names = setting_names()
>>> names["budget"], names["model_fitness"], names["pal.cga.elite"]
(('pal', 'budget'), ('pal', 'model_fitness'), ('pal', 'cga', 'elite'))
>>> "elite" in names
False
"""

from __future__ import annotations

import difflib
import math
import typing
from collections.abc import Iterator
from dataclasses import dataclass, fields, is_dataclass, replace
from functools import cache
from typing import Any

from pac_host import limits
from pac_host.coverage import MAX_REPS
from pac_host.errors import InputError
from pac_host.experiments.experiment import ExperimentConfig, default_methods
from pac_host.learning import pal, profiles
from pac_host.search.shorten import MAX_SHORTEN_AFTER
from pac_host.typed_values import coerce

TABLE_SETTINGS = {"actual": "shifted", "model": "measured", "effects": ()}
# the profile a cell's PAL settings start from; "none": the configuration's own defaults
PROFILE = "profile"
NO_PROFILE = "none"

# Fields every PAL run of the experiment sets itself: sweeping them would change nothing.
SET_BY_THE_EXPERIMENT = {
    ("pal", "method"): "methods",
    ("pal", "generations"): "generations",
    ("pal", "cga", "population"): "cga_population",
    ("pal", "cga", "budget"): "budget",
    ("pal", "model", "population"): "model_population",
    ("pal", "model", "budget"): "budget",
}

Path_ = tuple[str, ...]


@dataclass(frozen=True)
class Span:
    """An interval a number may take (``lo_open``/``hi_open``: the end itself is out; ``hi``
    None: no upper end), and what such a number is."""

    lo: float
    hi: float | None
    what: str = ""
    lo_open: bool = False
    hi_open: bool = False

    def describe(self) -> str:
        hi = "inf)" if self.hi is None else f"{self.hi:g}{')' if self.hi_open else ']'}"
        return f"{'(' if self.lo_open else '['}{self.lo:g}, {hi}"

    def check(self, value: float, name: str) -> None:
        ok = math.isfinite(value) and (value > self.lo if self.lo_open else value >= self.lo)
        if ok and self.hi is not None:
            ok = value < self.hi if self.hi_open else value <= self.hi
        if not ok:
            why = f" ({self.what})" if self.what else ""
            raise InputError(f"{name} must be in {self.describe()}{why}, got {value}")


PROBABILITY = Span(0.0, 1.0, "a probability")
_POPULATION = limits.Bound(0, limits.CGA_POPULATION.hi)
# The range of every number a sweep may set, checked as the sweep file is read, before any cell
# runs (tests/host/test_sweep_checks.py checks that every numeric setting has one). Choices
# (methods, correction, ...) are checked by the configs themselves.
RANGES: dict[Path_, limits.Bound | Span] = {
    ("seeds",): limits.SEEDS,
    ("generations",): limits.GENERATIONS,
    ("base_seed",): limits.SEED,
    ("initial_generations",): limits.GENERATIONS,
    ("optimum_runs",): limits.RUNS,
    ("optimum_generations",): limits.GENERATIONS,
    ("optimum_evaluations",): limits.EVALUATIONS,
    ("best_known",): limits.Bound(1, 10**6, "a coverage fitness"),
    ("pal", "interval"): limits.INTERVAL,
    ("pal", "model_generations"): limits.MODEL_GENERATIONS,
    ("pal", "cga_population"): limits.CGA_POPULATION,
    ("pal", "model_population"): limits.MODEL_POPULATION,
    ("pal", "budget"): limits.BUDGET,
    ("pal", "perturb_prob"): PROBABILITY,
    ("pal", "perturb_reps"): limits.Bound(0, MAX_REPS, "a gene's repetitions"),
    ("pal", "search_evaluations"): limits.Bound(0, limits.SEARCH_EVALUATIONS.hi),
    ("pal", "search_models"): limits.SEARCH_MODELS,
    ("pal", "search_chains"): limits.CHAINS,
    ("pal", "noisy_search_scale"): limits.NOISY_SEARCH_SCALE,
    ("pal", "explore"): Span(0.0, 1.0, "a share of the budget", hi_open=True),
    ("pal", "kick_length_cost"): Span(0.0, None, "cm"),
    ("pal", "shorten_after"): limits.Bound(0, MAX_SHORTEN_AFTER, "kicks"),
    ("pal", "cga", "elite"): _POPULATION,
    ("pal", "cga", "tournament_size"): limits.Bound(1, limits.CGA_POPULATION.hi),
    ("pal", "cga", "crossover_rate"): PROBABILITY,
    ("pal", "cga", "bit_mutation_rate"): PROBABILITY,
    ("pal", "model", "elite"): _POPULATION,
    ("pal", "model", "tournament_size"): limits.Bound(1, limits.MODEL_POPULATION.hi),
    ("pal", "model", "crossover_rate"): PROBABILITY,
    ("pal", "model", "gene_mutation_rate"): PROBABILITY,
    ("pal", "model", "scale"): Span(0.0, None, "a standard deviation, cm, cm and deg"),
}


def _in_range(key: str, value: Any) -> Any:
    """``value`` (checked against its type) if it is in its setting's range (each of a list's
    numbers), else one line naming the setting and the range."""
    bound = RANGES.get(setting_names().get(key, ()))
    if bound is not None and value is not None:
        for v in value if isinstance(value, list) else [value]:
            bound.check(v, f"setting {key!r}")
    return value


def _leaves(cls: type, prefix: Path_ = ()) -> Iterator[tuple[Path_, Any]]:
    hints = typing.get_type_hints(cls)
    for f in fields(cls):
        hint = hints[f.name]
        if is_dataclass(hint):
            yield from _leaves(hint, prefix + (f.name,))
        else:
            yield prefix + (f.name,), hint


@cache
def _field_types(cls: type = ExperimentConfig) -> dict[Path_, Any]:
    return dict(_leaves(cls))


@cache
def setting_names(cls: type = ExperimentConfig) -> dict[str, Path_]:
    """Every name a setting may go by: its dotted path, and its field name where that is the
    shallowest of its name and unique at its depth."""
    paths = [p for p in _field_types(cls) if p not in SET_BY_THE_EXPERIMENT]
    names = {".".join(p): p for p in paths}
    by_name: dict[str, list[Path_]] = {}
    for p in paths:
        by_name.setdefault(p[-1], []).append(p)
    for name, ps in by_name.items():
        depth = min(len(p) for p in ps)
        top = [p for p in ps if len(p) == depth]
        if len(top) == 1:
            names.setdefault(name, top[0])
    return names


def canonical_name(key: str) -> str:
    """The short name of a setting (``pal.budget`` -> ``budget``); an unknown one is an error."""
    key = key.strip().replace("-", "_")
    if key in TABLE_SETTINGS or key == PROFILE:
        return key
    names = setting_names()
    if key not in names:
        known = sorted(set(names) | set(TABLE_SETTINGS) | {PROFILE})
        path = tuple(key.split("."))
        if path in SET_BY_THE_EXPERIMENT:
            hint = f" (the experiment sets it; sweep {SET_BY_THE_EXPERIMENT[path]!r})"
        else:
            close = difflib.get_close_matches(key, known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise InputError(f"unknown setting {key!r}{hint}")
    path = names[key]
    return min((n for n, p in names.items() if p == path), key=len)


def check_value(key: str, value: Any) -> Any:
    """A setting's value, checked and in its JSON form (``key`` is canonical)."""
    if key in ("actual", "model"):
        return coerce(value, str, f"setting {key!r}")
    if key == PROFILE:
        name = coerce(value, str, f"setting {key!r}")
        choices = [*profiles.PROFILES, NO_PROFILE]
        if name not in choices:
            raise InputError(f"setting 'profile' takes {', '.join(choices)}, got {name!r}")
        return name
    if key == "effects":
        return (coerce(value, tuple[str, ...], f"setting {key!r}") if not isinstance(value, str)
                else [value])
    return _in_range(key, coerce(value, _field_types()[setting_names()[key]],
                                 f"setting {key!r}"))


def _set(obj: Any, path: Path_, value: Any) -> Any:
    if len(path) == 1:
        return replace(obj, **{path[0]: value})
    return replace(obj, **{path[0]: _set(getattr(obj, path[0]), path[1:], value)})


def experiment_config(settings: dict[str, Any]) -> ExperimentConfig:
    """The config a cell's (canonical, checked) settings make over its profile's (the
    defaults without one), checked as the CLI's is."""
    profile = settings.get(PROFILE, NO_PROFILE)
    cfg = ExperimentConfig()
    if profile != NO_PROFILE:
        cfg = replace(cfg, pal=profiles.apply(profile, pal.PALConfig()),
                      optimum_search=profiles.OPTIMUM_SEARCH[profile])
    for key, value in settings.items():
        if key in TABLE_SETTINGS or key == PROFILE:
            continue
        path = setting_names()[key]
        if isinstance(value, list):
            value = tuple(value)
        cfg = _set(cfg, path, value)
    if "methods" not in settings:
        cfg = replace(cfg, methods=default_methods(cfg.pal))
    cfg.check()
    for ga, population in (("cga", cfg.pal.cga_population), ("model", cfg.pal.model_population)):
        for name, most in (("elite", population - 1), ("tournament_size", population)):
            if getattr(getattr(cfg.pal, ga), name) > most:
                raise InputError(f"setting 'pal.{ga}.{name}' must be at most {most} with "
                                 f"{ga}_population {population}, got "
                                 f"{getattr(getattr(cfg.pal, ga), name)}")
    return cfg
