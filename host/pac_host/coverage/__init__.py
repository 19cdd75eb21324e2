"""The coverage simulator (DESIGN.md 2.3): the hot loop of everything.

Runs whole populations of turn cycles on one or many gait tables at once with numpy, and scores
each path: blocks covered, blocks covered exactly once, the coverage fitness ``3 R + c`` and
repeat visits.

The area is x in [0, 180) cm, y >= 0, in 60 x 60 cm blocks (3 columns, rows unbounded upward);
a block is detected when the 12 cm body width, perpendicular to the heading at the body's mid
point, lies inside it. Detection is checked at the start pose and after every gait cycle.

The package's modules, by job: :mod:`~pac_host.coverage.area` (the area and block detection),
:mod:`~pac_host.coverage.turn_cycle` (turn cycles: text form, limits, budget, looping),
:mod:`~pac_host.coverage.scores` (coverage figures and the scores ranked by them),
:mod:`~pac_host.coverage.engine` (the simulator: :func:`simulate`, :class:`Scorer`),
:mod:`~pac_host.coverage.kernel` (its compiled kernel) and :mod:`~pac_host.coverage.placement`
(start poses of a robot placed by hand). The public names of the first four are here.

>>> from pac_host.model import measured_table
>>> cov = simulate(measured_table().rows, parse_turn_cycle("12:63"))  # straight on, eastward
>>> cov.row(0)  # row 0 swept once, then the robot leaves the area
{'blocks_covered': 3, 'blocks_covered_once': 3, 'fitness': 3, 'repeat_visits': 0}
"""

from __future__ import annotations

from pac_host.coverage.area import (
    AREA_WIDTH_CM,
    BLOCK_CM,
    COLUMNS,
    HALF_BODY_CM,
    START_POSE,
    detect_blocks,
)
from pac_host.coverage.engine import CHUNK_PATHS, Scorer, simulate
from pac_host.coverage.scores import (
    Coverage,
    coverage_of_poses,
    coverage_score,
    figures_from_blocks,
    fitness_of_score,
    fitness_of_search_score,
    pooled_search_score,
    search_score,
)
from pac_host.coverage.turn_cycle import (
    DEFAULT_BUDGET,
    MAX_GAIT_ID,
    MAX_GENES,
    MAX_REPS,
    check_budget,
    expand,
    format_turn_cycle,
    parse_turn_cycle,
)

__all__ = [
    "AREA_WIDTH_CM",
    "BLOCK_CM",
    "CHUNK_PATHS",
    "COLUMNS",
    "DEFAULT_BUDGET",
    "HALF_BODY_CM",
    "MAX_GAIT_ID",
    "MAX_GENES",
    "MAX_REPS",
    "START_POSE",
    "Coverage",
    "Scorer",
    "check_budget",
    "coverage_of_poses",
    "coverage_score",
    "detect_blocks",
    "expand",
    "figures_from_blocks",
    "fitness_of_score",
    "fitness_of_search_score",
    "format_turn_cycle",
    "parse_turn_cycle",
    "pooled_search_score",
    "search_score",
    "simulate",
]
