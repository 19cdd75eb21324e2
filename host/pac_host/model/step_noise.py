"""Step noise: a real robot never walks the same gait cycle twice.

Each executed gait cycle moves the robot by its row (F, T, dH), after the effects, plus an
independent Gaussian draw with a standard deviation per component: cm on F and T, degrees on
dH, optionally per gait cycle id (turns noisier than straights). It is the robot's own
variability, not the tracker's: the path wanders and its heading errors add up over a run.
A model predicts with it through many walks (the expected coverage), never by one.

The one definition, used by the simulated robots (experiment), the emulator's world
(``pac-sim``), ``simulate --walks`` and the search's noisy objective.

>>> n = parse_step_noise("0.3,1")
>>> n.sd[12].tolist(), n.is_zero()
([0.3, 0.3, 1.0], False)
>>> parse_step_noise("0").is_zero(), parse_step_noise("none").is_zero()
(True, True)
>>> step_noise_from_json(n.to_json()) == n
True
>>> d = n.draw(np.array([12, 12, 3]), np.random.default_rng(0))
>>> d.shape
(3, 3)
>>> from pac_host.model.table import measured_table
>>> body, _ = noisy_step_moves(measured_table().rows, np.array([12, 12]), (), n,
...                            np.random.default_rng(0))
>>> bool((body != measured_table().rows[[12, 12]]).all())
True
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.errors import InputError
from pac_host.model.effects import Effect, step_moves

N_IDS = 32
# Larger deviations describe no walking robot (a gait cycle moves at most about 12 cm and
# turns at most about 27 deg): a value past these is a typo, refused before any work.
MAX_CM = 10.0
MAX_DEG = 30.0


@dataclass(frozen=True, eq=False)
class StepNoise:
    """Standard deviations of each executed gait cycle's move, (32, 3): cm F, cm T, deg dH."""

    sd: np.ndarray

    def __post_init__(self) -> None:
        sd = np.array(self.sd, dtype=np.float64)
        if sd.shape == (3,):
            sd = np.broadcast_to(sd, (N_IDS, 3)).copy()
        if sd.shape != (N_IDS, 3):
            raise InputError(f"step noise takes 3 deviations or 32 x 3, got shape {sd.shape}")
        check_deviations(sd)
        sd.setflags(write=False)
        object.__setattr__(self, "sd", sd)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, StepNoise) and bool(np.array_equal(self.sd, other.sd))

    def __hash__(self) -> int:
        return hash(self.sd.tobytes())

    def is_zero(self) -> bool:
        return not self.sd.any()

    def uniform(self) -> tuple[float, float] | None:
        """(cm, deg) if every gait cycle has the same deviations with F and T alike, else None."""
        first = self.sd[0]
        if (self.sd == first).all() and first[0] == first[1]:
            return float(first[0]), float(first[2])
        return None

    def draw(self, gait_ids: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """One draw of noise (..., 3) for each executed gait cycle in ``gait_ids``."""
        gait_ids = np.asarray(gait_ids, dtype=np.int64)
        return self.errors(gait_ids, rng.standard_normal(gait_ids.shape + (3,)))

    def errors(self, gait_ids: np.ndarray, z: np.ndarray) -> np.ndarray:
        """The noise (..., 3) of executed gait cycles ``gait_ids`` from standard normals ``z``
        (broadcast against ``gait_ids.shape + (3,)``): ``z * sd``, per component."""
        return z * self.sd[np.asarray(gait_ids, dtype=np.int64)]

    def to_text(self) -> str:
        u = self.uniform()
        return "none" if self.is_zero() else (f"{u[0]:g},{u[1]:g}" if u else "per-cycle")

    def to_json(self) -> dict:
        """``{"F": cm, "T": cm, "dH": deg}`` when uniform, else
        ``{"per_cycle": 32 x [F, T, dH]}``."""
        if (self.sd == self.sd[0]).all():
            return {"F": float(self.sd[0, 0]), "T": float(self.sd[0, 1]),
                    "dH": float(self.sd[0, 2])}
        return {"per_cycle": self.sd.tolist()}


def check_deviations(sd: np.ndarray, what: str = "step noise") -> None:
    """One line for a negative, non-finite or absurd deviation."""
    sd = np.asarray(sd, dtype=np.float64)
    if not np.isfinite(sd).all():
        raise InputError(f"{what}: deviations must be finite numbers")
    if (sd < 0).any():
        raise InputError(f"{what}: deviations must be >= 0, got {sd.min():g}")
    cm, deg = sd[..., :2].max(initial=0.0), sd[..., 2].max(initial=0.0)
    if cm > MAX_CM or deg > MAX_DEG:
        raise InputError(f"{what}: at most {MAX_CM:g} cm on F and T and {MAX_DEG:g} deg on dH "
                         f"a gait cycle (a walking robot varies far less), got {cm:g} cm, "
                         f"{deg:g} deg")


NONE = StepNoise(np.zeros(3))


def parse_step_noise(text: str) -> StepNoise:
    """``CM,DEG`` (F and T in cm, dH in degrees, every gait cycle), or ``0`` / ``none``."""
    text = text.strip()
    if text.lower() in ("none", "0", ""):
        return NONE
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        cm, deg = (float(p) for p in parts)
    except ValueError:
        raise InputError(f"--step-noise takes CM,DEG (e.g. 0.3,1) or none, got {text!r}") from None
    if not (math.isfinite(cm) and math.isfinite(deg)):
        raise InputError(f"--step-noise: deviations must be finite numbers, got {text!r}")
    return StepNoise(np.array([cm, cm, deg]))


def step_noise_from_json(doc: object, source: str = "step_noise") -> StepNoise:
    """A gait table's ``step_noise``: ``{"F": cm, "T": cm, "dH": deg}`` or
    ``{"per_cycle": [[F, T, dH], ...32]}``."""
    if not isinstance(doc, dict):
        raise InputError(f"{source}: must be an object like {{\"F\": 0.3, \"T\": 0.3, \"dH\": 1}}")
    if "per_cycle" in doc:
        rows = doc["per_cycle"]
        if not (isinstance(rows, list) and len(rows) == N_IDS
                and all(isinstance(r, list) and len(r) == 3 for r in rows)):
            raise InputError(f"{source}: per_cycle must be 32 rows of [F, T, dH]")
        values = [v for r in rows for v in r]
    else:
        missing = [k for k in ("F", "T", "dH") if k not in doc]
        if missing:
            raise InputError(f"{source}: missing {', '.join(missing)}")
        values = [doc["F"], doc["T"], doc["dH"]]
    if any(isinstance(v, bool) or not isinstance(v, int | float) for v in values):
        raise InputError(f"{source}: deviations must be numbers")
    sd = np.array(values, dtype=np.float64).reshape(-1, 3)
    sd = sd[0] if "per_cycle" not in doc else sd
    check_deviations(sd, source)
    return StepNoise(sd)


def noisy_step_moves(
    rows: np.ndarray,
    gait_ids: np.ndarray,
    effects: Sequence[Effect],
    noise: StepNoise,
    rng: np.random.Generator | None,
    n0: int | np.ndarray = 0,
    prev_gait: int | None = None,
    effect_rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """The moves a robot really makes on a run: :func:`~pac_host.model.effects.step_moves`
    (body (..., n, 3), world drift or None; ``n0``, ``prev_gait`` and ``effect_rng`` as there)
    with one draw of ``noise`` from ``rng`` added to each executed gait cycle's body move.

    The one place a noisy move is drawn (the experiment's robot, the emulator's world,
    ``simulate --walks``). Zero noise draws nothing: step_moves' moves value for value.
    """
    gait_ids = np.asarray(gait_ids)
    body, world = step_moves(rows, gait_ids, effects, n0, prev_gait, effect_rng)
    if noise.is_zero():
        return body, world
    if rng is None:
        raise ValueError("step noise needs a Generator to draw from")
    return body + noise.draw(gait_ids, rng), world
