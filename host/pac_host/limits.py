"""The ranges the counts a user gives may take: one definition for the CLI and the configs.

A count outside its range is bad input (exit 2), caught before any work starts, so a typo such
as ``--budget 100000000`` is one line, not minutes of computing and 10^8 printed poses.

>>> BUDGET.check(200, "--budget")
200
>>> try:
...     BUDGET.check(100_000_000, "--budget")
... except InputError as e:
...     print(e)
--budget must be 1..65535 (the firmware counts gait cycles in 16 bits), got 100000000
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pac_host.errors import InputError

MAX_GAIT_CYCLES = 65535  # the firmware counts gait cycles in a 16-bit word


@dataclass(frozen=True)
class Bound:
    """An inclusive integer range, with the reason for its limit when it is not obvious."""

    lo: int
    hi: int
    why: str = ""

    def check(self, value: object, name: str) -> int:
        """``value`` as an int, or :class:`InputError` naming ``name``, the range and the value."""
        ok = isinstance(value, int | np.integer) and not isinstance(value, bool)
        if not ok or not self.lo <= value <= self.hi:
            why = f" ({self.why})" if self.why else ""
            raise InputError(f"{name} must be {self.lo}..{self.hi}{why}, got {value}")
        return int(value)

    def describe(self) -> str:
        return f"{self.lo}..{self.hi}"


_FIRMWARE = "the firmware counts gait cycles in 16 bits"
BUDGET = Bound(1, MAX_GAIT_CYCLES, _FIRMWARE)  # gait cycles of one test run
SIM_BUDGET = Bound(0, MAX_GAIT_CYCLES, _FIRMWARE)  # simulate: 0 scores the start pose alone
GENERATIONS = Bound(0, 100_000)  # CGA generations (the paper: 1000)
MODEL_GENERATIONS = Bound(0, 10_000)  # model GA generations per punctuation (the paper: 40)
INTERVAL = Bound(1, 100_000)  # CGA generations between punctuations
SEEDS = Bound(1, 10_000)
SEED = Bound(0, 2**63 - 1, "numpy's generators take non-negative seeds")  # a --seed
RUNS = Bound(1, 1_000)  # long optimum runs
CGA_POPULATION = Bound(4, 100_000)
MODEL_POPULATION = Bound(4, 10_000)
REPEATS = Bound(2, 1_000)  # measure: placements per gait cycle id
EVALUATIONS = Bound(1, 10**11)  # coverage evaluations of one search (about 3 days on a core)
SEARCH_EVALUATIONS = Bound(1, 10**9)  # anytime search per punctuation (about an hour)
SEARCH_MODELS = Bound(1, 64)  # tables an anytime search pools each turn cycle over
CHAINS = Bound(1, 1_024)  # independent chains of one search
NOISY_SEARCH_SCALE = Bound(1, 1_000)  # a noisy anytime search's evaluations per noise-free one
WALKS = Bound(1, 100_000)  # simulate: walks from drawn start poses or with step noise
