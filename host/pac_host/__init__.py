"""pac-host: co-evolve the ServoBot's gait model and its area-coverage turn cycle.

Layers, bottom up: ``model`` (gait table, pose update, unmodelled effects), ``coverage``
(the vectorized coverage simulator), ``cga`` and ``model_ga`` (the two genetic algorithms),
``pal`` (punctuated anytime learning), ``experiment`` (the paper's experiment), ``cli``.
"""

__version__ = "0.1.0"
