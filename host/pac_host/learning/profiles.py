"""Named settings profiles: each is a dict of :class:`pac_host.learning.pal.PALConfig` field
overrides.

- ``paper``: the paper's method (:data:`pac_host.learning.pal.PAPER`: its model GA on the six
coverage
  differences, its tests, its operational rule) and its search, 40 generations of the plain
  CGA (population 128, today's operators) between punctuations; the experiment establishes its
  optimum with long CGA runs. It reproduces the figures published for the paper's experiment,
  seed for seed.
- ``default``: :class:`~pac_host.learning.pal.PALConfig`'s model side (the whole-table correction)
and
  anytime PAL: between punctuations the CGA's place is taken by iterated local search
  (:mod:`pac_host.search`) with a budget of coverage evaluations per punctuation, run while the
  robot walks the tests; the experiment's optimum comes from
  :func:`pac_host.search.optimize.optimize`. Each new model's search also starts from the
  project's library of good sweeps re-expressed on it (:mod:`pac_host.search.shapes`). A
  quarter of each budget searches a draw from the corrected model's posterior, whose best is
  tested after the best (``explore``: Thompson sampling). Eight chains search each corrected
  model, each with the whole budget, and the best any finds is tested (``search_chains``:
  climbs from one start end in different basins; docs/explanation/learning.md). A closing kick
  weighs
  each gait cycle of the kicked loop as 1 cm of its repair's error (``kick_length_cost``:
  the same sweep in fewer gait cycles is walked more times in the budget; on noisy_rows 22/30
  runs end at 95% of the best known against 16/30 without it, no robot lower;
  docs/explanation/learning.md).
  A chain that has kicked five times without progress tries shorter loops of its sweep, two
  genes re-set so the pass ends where it did (``shorten_after``, :mod:`pac_host.search.shorten`),
  and if none climbs higher, four consecutive genes re-set (``shorten_windows``). A chain's
  find on the model before moves its point on the new model, but its restarts climb the
  library's best start, not that find again (``library_restarts``). A chain whose budget
  runs out mid-move ends the move and pays the excess from its next budget
  (``finish_moves``): a shorter-window try costs about a punctuation's budget and was lost.
  Each punctuation's correction fits the sequence and world effects' parameters again with the
  rows on every run (``refine_effects``): the selection's estimate from its latest runs left
  the rows a misfit that moved the predicted coverage by blocks.
  Once the robot's step noise is estimated clearly above zero, the operational turn cycle is
  chosen on all its walks and the model's prediction, not on one walk
  (``operational_evidence``, :mod:`pac_host.learning.operational`); without step noise the
  rule is the last-walk one, figure for figure. The search then ranks turn cycles by their
  expected coverage over noisy walks of the model with the estimated noise (``search_noise``,
  :mod:`pac_host.learning.anytime_search`), and the tests' predictions are expectations.
  A noisy search is given :data:`NOISY_SEARCH_SCALE` times the evaluations
  (``noisy_search_scale``): an evaluation is then one of the 32 walks a turn cycle costs, and
  the chains' finds are ranked on 400 fresh walks of the model before the best is tested.

Other settings (e.g. of the model GA) may be added to a profile as further overrides; a key
must name a ``PALConfig`` field.
"""

from __future__ import annotations

from dataclasses import fields, replace

from pac_host.errors import InputError
from pac_host.learning.config import PAPER
from pac_host.search.kicks import SHORTER
from pac_host.search.shorten import SHORTEN_AFTER

# a noisy search's evaluations per noise-free one in the default profile: at 32 walks a turn
# cycle, one budget scores 32 times fewer turn cycles, and PAL's search then ended where a
# minute of `optimize --step-noise` on the true table ends. Four times ended PAL's search on
# the exact shifted table higher (23.82 against 23.24 over seeds 0-3), but the whole runs no
# higher, at two thirds more time (docs/results.md, "Step noise")
NOISY_SEARCH_SCALE = 2

PROFILES: dict[str, dict] = {
    "paper": {**PAPER, "search": "cga"},
    "default": {"search": "ils", "search_evaluations": 400_000, "shapes": "builtin",
                "explore": 0.25, "search_chains": 8, "kick_length_cost": SHORTER,
                "shorten_after": SHORTEN_AFTER, "shorten_windows": True,
                "library_restarts": True, "finish_moves": True, "refine_effects": True,
                "operational_evidence": True, "search_noise": True,
                "noisy_search_scale": NOISY_SEARCH_SCALE},
}
DEFAULT = "default"
# how an experiment establishes the optimum on the actual robot, per profile
OPTIMUM_SEARCH = {"paper": "cga", "default": "optimize"}


def apply(profile: str, cfg):
    """``cfg`` (a PALConfig) with the profile's overrides."""
    if profile not in PROFILES:
        raise InputError(f"unknown profile {profile!r}; use one of {', '.join(PROFILES)}")
    names = {f.name for f in fields(cfg)}
    bad = set(PROFILES[profile]) - names
    if bad:
        raise ValueError(f"profile {profile} overrides unknown PALConfig fields {sorted(bad)}")
    return replace(cfg, **PROFILES[profile])
