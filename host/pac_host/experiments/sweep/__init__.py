"""Sweeps: many experiments over a grid of settings, on this machine or a Dask cluster."""

from pac_host.experiments.sweep.runner import run_sweep, setting_keys, varying_keys
from pac_host.experiments.sweep.spec import Cell, load_sweep, parse_sweep

__all__ = ["Cell", "load_sweep", "parse_sweep", "run_sweep", "setting_keys", "varying_keys"]
