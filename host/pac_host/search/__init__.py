"""Searches for a turn cycle on a model: local search over single-gene changes, iterated local
search, and the optimizer behind ``pac-host optimize`` and the experiment's optimum."""
