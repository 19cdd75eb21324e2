"""Experiments over many seeds and sweeps over grids of settings."""
