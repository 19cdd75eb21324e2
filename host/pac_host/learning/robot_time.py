"""Robot time: what a test costs in hours of walking and placing the robot.

Learning methods are compared by what users pay for, robot time (DESIGN.md 2.6). The period of
each gait cycle in a run (the gait cycle plus the boundary: CYCLE and READY frames and the
100 ms listening window) was measured on ``firmware/servobot.bs2`` in the project's PBASIC
interpreter, in Stamp time, by id (a turn's dragging hips get fewer pulses, so harder turns are
shorter): 1.30 s for the hardest turns to 1.44 s straight (firmware/README.md: gait cycle
1.17-1.31 s, period 1.43 s for gait 15). ``tests/pbasic/test_pbasic_gait_period.py`` re-measures
them. Placing the robot at the start pose is a person's job: ``PLACE_S`` per test is a project
assumption (DESIGN.md 2.6 puts a punctuation of three 200-cycle tests at 13-15 minutes).

>>> import numpy as np
>>> round(float(seconds_of_tests(np.array([[[15, 10]]]), 200)[0]), 1)  # 200 straight cycles, placed
348.0
"""

from __future__ import annotations

import numpy as np

from pac_host.coverage import expand

# Seconds per gait cycle in a run, by id 0..31 (right turns 0..15, left turns 16..31).
GAIT_PERIOD_S = np.array([
    1.303, 1.314, 1.325, 1.335, 1.346, 1.356, 1.366, 1.375,
    1.385, 1.394, 1.403, 1.411, 1.420, 1.428, 1.436, 1.440,
    1.301, 1.309, 1.317, 1.326, 1.334, 1.343, 1.352, 1.362,
    1.371, 1.381, 1.391, 1.402, 1.412, 1.423, 1.434, 1.440,
])
PLACE_S = 60.0  # placing the robot at the start pose before each test (assumption)


def seconds_of_tests(tests: np.ndarray, budget: int) -> np.ndarray:
    """Robot seconds of each test (k, 9, 2): its gait cycles' periods plus one placing."""
    ids, still = expand(np.asarray(tests), budget)
    walk = np.where(still, 0.0, GAIT_PERIOD_S[ids].sum(axis=1))
    return walk + PLACE_S
