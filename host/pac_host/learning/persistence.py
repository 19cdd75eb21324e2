"""A PAL run saved and resumed exactly: its state and generator as a ``pac-pal-state/1`` JSON
document (:func:`state_to_json`, :func:`state_from_json`)."""

from __future__ import annotations

import numpy as np

from pac_host.errors import InputError
from pac_host.learning import model_fit
from pac_host.learning.state import PALState


def _poses_json(poses: np.ndarray) -> list:
    """Observed poses as JSON: a gap (NaN: a gait cycle not seen) as null, which reads back as
    NaN."""
    if np.isfinite(poses).all():
        return poses.tolist()
    return [[v if np.isfinite(v) else None for v in p] for p in poses.tolist()]


def state_to_json(state: PALState, rng: np.random.Generator) -> dict:
    """Everything needed to resume a PAL run exactly: the state and the generator's state.

    Floats go through JSON's shortest round-trip representation, so a resumed run continues
    bit for bit.
    """
    return {
        "format": "pac-pal-state/1",
        "generation": state.generation,
        "cga_pop": state.cga_pop.tolist(),
        "models": state.models.tolist(),
        "model_effects": [e.to_json() for e in state.model_effects],
        "operational": state.operational.tolist(),
        "operational_score": state.operational_score,
        "operational_fitness": state.operational_fitness,
        "base": None if state.base is None else state.base.to_json(),
        "observed": [{"gait_ids": o.gait_ids.tolist(), "poses": _poses_json(o.poses),
                      "cycles_since_power_on": o.cycles_since_power_on}
                     for o in state.observed],
        "search": state.search,
        "structure": [e.to_json() for e in state.structure],
        "structure_runs": state.structure_runs,
        "walks": {k: list(v) for k, v in state.walks.items()},
        "repeat": None if state.repeat is None else state.repeat.tolist(),
        "step_noise": None if state.step_noise is None else state.step_noise.to_json(),
        "rng": rng.bit_generator.state,
    }


def _search_from_json(doc) -> dict | None:
    """The carried search of a state document, checked (None: none carried)."""
    if doc is None:
        return None
    from pac_host.search.local import Chain

    out = Chain.from_json(doc).to_json()
    others = doc.get("others") or []
    if not isinstance(others, list) or not all(isinstance(c, dict) for c in others):
        raise InputError("a carried search's other chains must be a list of chains")
    if others:  # chains 1.. of --search-chains
        out["others"] = [Chain.from_json(c).to_json() for c in others]
    if doc.get("explore") is not None:  # the best on a posterior draw, the next test
        out["explore"] = np.asarray(doc["explore"], dtype=np.int64).reshape(-1, 2).tolist()
    if doc.get("walks_seed") is not None:  # the noisy walks it last ranked with
        out["walks_seed"] = int(doc["walks_seed"])
    return out


def _walks_from_json(doc) -> dict[str, tuple[int, ...]]:
    """The walks of a state document, checked ({}: a state saved before they were kept)."""
    if doc is None:
        return {}
    if not isinstance(doc, dict) or not all(isinstance(v, list) for v in doc.values()):
        raise InputError("a PAL state's walks must map turn cycles to lists of fitnesses")
    return {str(k): tuple(int(f) for f in v) for k, v in doc.items()}


def state_from_json(doc: dict) -> tuple[PALState, np.random.Generator]:
    """Inverse of :func:`state_to_json`."""
    from pac_host.model.effects import effect_from_json
    from pac_host.model.step_noise import step_noise_from_json
    from pac_host.model.table import table_from_json

    if not isinstance(doc, dict) or doc.get("format") != "pac-pal-state/1":
        raise InputError("not a pac-pal-state/1 document")
    try:
        rng = np.random.default_rng()
        rng.bit_generator.state = doc["rng"]
        state = PALState(
            int(doc["generation"]),
            np.array(doc["cga_pop"], dtype=np.int64),
            np.array(doc["models"], dtype=np.float64),
            tuple(effect_from_json(e) for e in doc["model_effects"]),
            np.array(doc["operational"], dtype=np.int64),
            doc["operational_score"],
            doc["operational_fitness"],
            None if doc.get("base") is None else table_from_json(doc["base"], "PAL state base"),
            tuple(model_fit.Observed(np.array(o["gait_ids"], dtype=np.int64),
                                     np.array(o["poses"], dtype=np.float64),
                                     int(o.get("cycles_since_power_on", 0)))
                  for o in doc.get("observed", [])),
            _search_from_json(doc.get("search")),
            tuple(effect_from_json(e) for e in doc.get("structure", [])),
            None if doc.get("structure_runs") is None else int(doc["structure_runs"]),
            _walks_from_json(doc.get("walks")),  # states saved before it: none kept
            None if doc.get("repeat") is None
            else np.array(doc["repeat"], dtype=np.int64).reshape(-1, 2),
            None if doc.get("step_noise") is None  # states saved before it: none
            else step_noise_from_json(doc["step_noise"], "PAL state step_noise"),
        )
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(f"PAL state is incomplete or malformed ({e})") from None
    return state, rng
