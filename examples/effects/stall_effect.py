"""A user-defined effect: the robot stalls on a share of its gait cycles.

Load it with ``--effects-module examples/effects/stall_effect.py`` in ``pac-host simulate``,
``experiment``, ``evolve`` (for ``--sim-effect``), ``diagnose`` and ``pac-sim``; then
``stall:p=0.2`` is an effect like any built-in one (``--effect``, ``--sim-effect``, a table's
``effects``), and the diagnosis tries it with the library's effects.
"""

import numpy as np

from pac_host.model.effects import ParamSpec, StepContext, register_effect


def stall(body: np.ndarray, ctx: StepContext, p: float) -> np.ndarray:
    """With probability p a gait cycle does not move the robot at all."""
    if ctx.rng is None:  # a model's prediction (diagnosis, coverage simulator): the expectation
        return body * (1.0 - p)
    moving = ctx.rng.random(body.shape[:-1]) >= p  # the simulated world draws the stalls
    return body * moving[..., None]


register_effect(
    "stall",
    [ParamSpec("p", 0.0, 0.9)],
    stall,
    doc="on a share p of gait cycles, at random, the robot does not move",
    reference={"p": 0.1},  # a moderate magnitude, for the diagnosis' identifiability check
)
