"""Diagnose the sim-to-real gap: where it lies, which unmodelled effect causes it, how far it
shrinks, checked on held-out runs. See docs/explanation/diagnosis.md for the method."""

from pac_host.diagnose.pipeline import Diagnosis, diagnose, split_runs
from pac_host.diagnose.runs import Run, read_runs, write_runs

__all__ = ["Diagnosis", "Run", "diagnose", "read_runs", "split_runs", "write_runs"]
