"""The robot model: gait tables, the pose update, and the unmodelled effects."""

from pac_host.model.effects import EFFECT_SPECS, Effect, parse_effect, step_moves
from pac_host.model.kinematics import integrate, rollout
from pac_host.model.table import (
    GaitTable,
    load_table,
    load_with_effects,
    measured_table,
    resolve_table,
    save_table,
    shifted_table,
)

__all__ = [
    "EFFECT_SPECS",
    "Effect",
    "GaitTable",
    "integrate",
    "load_table",
    "load_with_effects",
    "measured_table",
    "parse_effect",
    "resolve_table",
    "rollout",
    "save_table",
    "shifted_table",
    "step_moves",
]
