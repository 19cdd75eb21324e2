"""The best turn cycles known on the built-in robots, for the benchmarks that measure against
them: the package's one record (:mod:`pac_host.model.best_known`, ``best_known.json`` beside
it), which ``pac-host experiment`` measures against too.

>>> fitness("shifted") >= 49
True
>>> fitness("nobody") is None
True
"""

from __future__ import annotations

from pac_host.model.best_known import PATH, entries, fitness, fitnesses

__all__ = ["PATH", "entries", "fitness", "fitnesses"]
