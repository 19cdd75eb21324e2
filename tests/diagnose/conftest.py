"""Small simulated data sets for the diagnosis tests (seconds, not minutes)."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.diagnose.synth import cga_turn_cycles, world_runs
from pac_host.model import measured_table


@pytest.fixture(scope="session")
def cycles() -> np.ndarray:
    return cga_turn_cycles(np.random.default_rng(11), 40)


@pytest.fixture
def make_runs(cycles):
    def make(effects=(), n_runs=30, n_cycles=50, seed=0, pos=0.5, head=1.0):
        rng = np.random.default_rng(seed)
        return world_runs(measured_table().rows, list(effects), cycles[:n_runs], n_cycles, rng,
                          pos, head)
    return make
