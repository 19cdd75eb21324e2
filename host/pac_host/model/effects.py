"""Unmodelled effects (DESIGN.md section 3): named, parameterized transforms of a gait table.

This is the one definition of each effect. The emulator's simulated world moves the robot with
it, the coverage simulator plays "actual robots" with it, and the gap diagnosis fits it.

Effects compose in the canonical order of the design table, whatever order a file lists them:
table-level effects (``turn_shift`` .. ``lateral_slip``) rewrite the 32 rows, then sequence
effects (``transition``, ``battery_sag``) act on the executed steps, and ``floor_slope`` adds a
world-frame drift after each body-frame move.

>>> import numpy as np
>>> from pac_host.model.table import measured_table
>>> bias = Effect("yaw_bias", {"delta": 1.5})
>>> body, world = step_moves(measured_table().rows, np.array([12, 12]), [bias])
>>> body[:, 2].tolist()
[1.5, 1.5]
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.errors import InputError


@dataclass(frozen=True)
class ParamSpec:
    name: str
    lo: float
    hi: float
    integer: bool = False
    neutral: float = 0.0


@dataclass(frozen=True)
class StepContext:
    """What a sequence effect may depend on; arrays are shaped like the executed gait ids."""

    gait_ids: np.ndarray  # (..., n)
    prev_ids: np.ndarray  # (..., n): the gait cycle before each one in the run, -1 at its start
    since_power_on: np.ndarray  # (..., n): gait cycles executed since power-on before each one
    rng: np.random.Generator | None  # the world's randomness; None when a model predicts


@dataclass(frozen=True)
class EffectSpec:
    name: str
    params: tuple[ParamSpec, ...]
    stage: str  # "table", "sequence" or "world"
    doc: str
    # a user-defined effect: apply(body (..., n, 3), ctx, **params) -> body, see register_effect
    apply: Callable[..., np.ndarray] | None = None
    reference: dict | None = None  # a moderate magnitude, for the diagnosis' identifiability


EFFECT_SPECS: dict[str, EffectSpec] = {
    s.name: s
    for s in (
        EffectSpec("turn_shift", (ParamSpec("k", -15, 15, True, 0),), "table",
                   "every turn k strengths weaker (k > 0) or harder (k < 0)"),
        EffectSpec("turn_scale", (ParamSpec("c", 0.0, 3.0, neutral=1.0),), "table",
                   "lateral move and heading change scaled by c"),
        EffectSpec("stride_scale", (ParamSpec("a", 0.0, 3.0, neutral=1.0),), "table",
                   "forward move scaled by a"),
        EffectSpec("yaw_bias", (ParamSpec("delta", -30.0, 30.0),), "table",
                   "constant heading drift of delta degrees per gait cycle"),
        EffectSpec("lateral_slip", (ParamSpec("gamma", -2.0, 2.0),), "table",
                   "lateral slip of gamma cm per degree turned"),
        EffectSpec("transition", (ParamSpec("alpha", 0.0, 1.0),), "sequence",
                   "the first cycle after a change of gait is a blend with the previous gait"),
        EffectSpec("battery_sag", (ParamSpec("beta", 0.0, 0.1),), "sequence",
                   "every move shrinks by beta per gait cycle since power-on"),
        EffectSpec("floor_slope", (ParamSpec("s", -20.0, 20.0), ParamSpec("theta", -360.0, 360.0)),
                   "world", "a world-frame drift of s cm per gait cycle towards compass theta"),
    )
}
BUILT_IN = frozenset(EFFECT_SPECS)


def register_effect(
    name: str,
    params: Sequence[ParamSpec],
    apply: Callable[..., np.ndarray],
    doc: str = "",
    reference: dict | None = None,
) -> EffectSpec:
    """Add a user-defined effect to the one registry every command uses.

    ``apply(body, ctx, **params)`` gets the body-frame moves (..., n, 3) (F cm, T cm, dH deg)
    that the table and the built-in table and sequence effects give for the executed gait
    cycles, and a :class:`StepContext`; it returns the moves it makes instead, same shape. A
    random effect draws from ``ctx.rng`` in the simulated world and returns its expected move
    when ``ctx.rng`` is None (a model's prediction: the diagnosis, the coverage simulator).
    Parameters are continuous (``ParamSpec`` with ``integer=False``). It acts after the
    built-in sequence effects and before a world-frame drift; diagnosis fits it like the
    built-in ones.
    """
    if not name.isidentifier():
        raise InputError(f"effect {name!r}: the name must be an identifier")
    if name in BUILT_IN:
        raise InputError(f"effect {name!r}: a built-in effect of that name exists")
    if not callable(apply):
        raise InputError(f"effect {name!r}: apply must be a function")
    params = tuple(params)
    for p in params:
        if p.integer:
            raise InputError(f"effect {name!r}: parameter {p.name} must be continuous")
        if not p.lo <= p.neutral <= p.hi:
            raise InputError(f"effect {name!r}: neutral {p.name}={p.neutral} outside its range")
    spec = EffectSpec(name, params, "sequence", doc, apply, dict(reference) if reference else None)
    EFFECT_SPECS[name] = spec
    if reference is not None:
        Effect(name, dict(reference))  # checks the reference's parameters
    return spec


@dataclass(frozen=True)
class Effect:
    """One effect with its parameter values, e.g. ``Effect("yaw_bias", {"delta": 1.5})``."""

    name: str
    params: dict

    def __post_init__(self) -> None:
        spec = EFFECT_SPECS.get(self.name)
        if spec is None:
            raise InputError(
                f"unknown effect {self.name!r} (known: {', '.join(EFFECT_SPECS)})"
            )
        want = {p.name for p in spec.params}
        got = set(self.params)
        if got != want:
            raise InputError(
                f"effect {self.name}: parameters must be {sorted(want)}, got {sorted(got)}"
            )
        clean = {}
        for p in spec.params:
            v = self.params[p.name]
            if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
                raise InputError(f"effect {self.name}: {p.name} must be a number, got {v!r}")
            v = float(v)
            if not math.isfinite(v) or not p.lo <= v <= p.hi:
                raise InputError(
                    f"effect {self.name}: {p.name}={v} outside [{p.lo:g}, {p.hi:g}]"
                )
            if p.integer:
                if v != int(v):
                    raise InputError(f"effect {self.name}: {p.name} must be an integer")
                v = int(v)
            clean[p.name] = v
        object.__setattr__(self, "params", clean)

    def to_json(self) -> dict:
        return {"name": self.name, "params": dict(self.params)}

    def __str__(self) -> str:
        return self.name + ":" + ",".join(f"{k}={v:g}" for k, v in self.params.items())


def effect_from_json(doc: object, where: str = "effect") -> Effect:
    if not isinstance(doc, dict) or not isinstance(doc.get("name"), str):
        raise InputError(f"{where}: expected {{'name': ..., 'params': {{...}}}}")
    params = doc.get("params", {})
    if not isinstance(params, dict):
        raise InputError(f"{where}: 'params' must be an object")
    try:
        return Effect(doc["name"], params)
    except InputError as e:
        raise InputError(f"{where}: {e}") from None


def parse_effect(text: str) -> Effect:
    """Parse the command-line form ``name:param=value,...`` (``transition:alpha=0.4``)."""
    name, _, rest = text.partition(":")
    params: dict[str, float] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, val = item.partition("=")
        if not eq:
            raise InputError(f"effect {text!r}: expected name:param=value,...")
        try:
            params[key.strip()] = float(val)
        except ValueError:
            raise InputError(f"effect {text!r}: {key.strip()}={val!r} is not a number") from None
    return Effect(name.strip(), params)


def _canonical(effects: Iterable[Effect]) -> list[Effect]:
    order = list(EFFECT_SPECS)  # built-in effects first, user-defined ones as registered
    return sorted(effects, key=lambda e: order.index(e.name))


def effective_rows(rows: np.ndarray, effects: Iterable[Effect]) -> np.ndarray:
    """Apply the table-level effects to rows of shape (..., 32, 3); returns a new array."""
    out = np.array(rows, dtype=np.float64, copy=True)
    for e in _canonical(effects):
        p = e.params
        if e.name == "turn_shift":
            ids = np.arange(32)
            src = (ids & 16) | np.clip((ids & 15) + p["k"], 0, 15)
            out = out[..., src, :]
        elif e.name == "turn_scale":
            out[..., 1:] *= p["c"]
        elif e.name == "stride_scale":
            out[..., 0] *= p["a"]
        elif e.name == "yaw_bias":
            out[..., 2] += p["delta"]
        elif e.name == "lateral_slip":
            out[..., 1] += p["gamma"] * out[..., 2]
    return out


def gather_rows(rows: np.ndarray, gait_ids: np.ndarray) -> np.ndarray:
    """Rows of the executed gait cycles: (32, 3) or (K, 32, 3) rows, ids (..., n) or (K, ..., n)."""
    if rows.ndim == 2:
        return np.take(rows, gait_ids, axis=0)
    k = rows.shape[0]
    base = (np.arange(k) * 32).reshape((k,) + (1,) * (gait_ids.ndim - 1))
    return np.take(rows.reshape(-1, rows.shape[-1]), gait_ids + base, axis=0)


def sequence_effects(effects: Iterable[Effect]) -> list[Effect]:
    """The effects that depend on the executed sequence, not just on the gait id."""
    return [e for e in effects if EFFECT_SPECS[e.name].stage == "sequence"]


def world_drift(effects: Iterable[Effect]) -> np.ndarray | None:
    """The world-frame drift (dx, dy) per gait cycle, or None when no effect adds one."""
    for e in effects:
        if e.name == "floor_slope":
            th = math.radians(e.params["theta"])
            return np.array([e.params["s"] * math.sin(th), e.params["s"] * math.cos(th)])
    return None


def sag_factor(beta: float, n0: int | np.ndarray, n: int) -> np.ndarray:
    """``battery_sag``'s scale of each of a run's ``n`` moves (..., n): 1 less ``beta`` per gait
    cycle since power-on (``n0`` before the run), never below 0."""
    return np.maximum(0.0, 1.0 - beta * (np.asarray(n0)[..., None] + np.arange(n)))


def step_moves(
    rows: np.ndarray,
    gait_ids: np.ndarray,
    effects: Sequence[Effect] = (),
    n0: int | np.ndarray = 0,
    prev_gait: int | None = None,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Body-frame moves (..., n, 3) and world-frame drifts (..., n, 2) or None of a run.

    ``n0`` is the number of gait cycles executed since power-on before the run; ``prev_gait``
    is the gait executed just before ``gait_ids[0]`` in the same run (None at a run's start),
    which lets the emulator's world advance one gait cycle at a time. ``rng`` is the world's
    randomness for random user-defined effects (None: their expected move).
    """
    effects = _canonical(effects)
    gait_ids = np.asarray(gait_ids)
    table = effective_rows(rows, effects)
    body = gather_rows(table, gait_ids)
    for e in effects:
        p = e.params
        if e.name == "transition" and p["alpha"] > 0:
            prev = body.copy()  # a run's first step keeps its own move unless prev_gait is given
            prev[..., 1:, :] = body[..., :-1, :]
            changed = np.zeros(gait_ids.shape, dtype=bool)
            changed[..., 1:] = gait_ids[..., 1:] != gait_ids[..., :-1]
            if prev_gait is not None and gait_ids.shape[-1] > 0:
                first = np.full(gait_ids.shape[:-1] + (1,), prev_gait)
                prev[..., 0, :] = gather_rows(table, first)[..., 0, :]
                changed[..., 0] = gait_ids[..., 0] != prev_gait
            a = p["alpha"]
            body = np.where(changed[..., None], (1 - a) * body + a * prev, body)
        elif e.name == "battery_sag" and p["beta"] > 0:
            body = body * sag_factor(p["beta"], n0, gait_ids.shape[-1])[..., None]
    user = [e for e in effects if EFFECT_SPECS[e.name].apply is not None]
    if user:
        ctx = _context(gait_ids, n0, prev_gait, rng)
        for e in user:
            out = np.asarray(EFFECT_SPECS[e.name].apply(body.copy(), ctx, **e.params), float)
            if out.shape != body.shape:
                raise InputError(f"effect {e.name}: apply returned shape {out.shape}, "
                                 f"expected {body.shape}")
            body = out
    drift = world_drift(effects)
    world = None if drift is None else np.broadcast_to(drift, body.shape[:-1] + (2,))
    return body, world


def _context(gait_ids: np.ndarray, n0: int | np.ndarray, prev_gait: int | None,
             rng: np.random.Generator | None) -> StepContext:
    prev = np.full(gait_ids.shape, -1, dtype=np.int64)
    prev[..., 1:] = gait_ids[..., :-1]
    if prev_gait is not None and gait_ids.shape[-1] > 0:
        prev[..., 0] = prev_gait
    since = np.asarray(n0)[..., None] + np.arange(gait_ids.shape[-1])
    return StepContext(gait_ids, prev, np.broadcast_to(since, gait_ids.shape), rng)
