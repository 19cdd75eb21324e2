"""Which turn cycles the robot tests: the paper's perturbations, or tests that teach.

The paper tests the CGA's best turn cycle and two perturbations of it: tests chosen for
coverage, not for what they teach about the model. The ``informative`` choice follows Bongard
and Lipson's estimation-exploration algorithm: among candidate turn cycles near the best (the
paper's two perturbations and the best distinct turn cycles of the CGA's population), run the
ones on which the population of models disagrees most about the coverage the robot will reach.
Ties (models that agree, e.g. early on) go to the test that uses rows with the least evidence:
the most posterior variance over the steps it would walk.

The best turn cycle itself is always test 0: it is the one the robot's operational solution is
judged by.

The ``rows`` choice (the default of ``evolve`` and ``experiment``) adds candidates that teach
the rows no test has walked: the best turn cycle with one pair's gait cycle swapped for one
of the rows of most posterior variance it does not use (:func:`teaching_variants`). The
informative choice's candidates all stay near the best, so rows no sweep near it uses stay
unwalked for a whole run; the smooth prior extrapolates them, and where it extrapolates
wrongly (the end of the strength range) the search, which trusts the model, never goes there
(docs/explanation/learning.md, "Tests that walk the rows no test has walked").

>>> import numpy as np
>>> from pac_host.model import measured_table
>>> from pac_host.learning.model_ga import perturbed_population
>>> rng = np.random.default_rng(0)
>>> models = perturbed_population(measured_table().rows, 8, rng)
>>> pop = np.array([[[12, 20], [3, 8]], [[12, 20], [3, 8]], [[12, 5], [20, 9]],
...                 [[26, 30], [4, 12]]])
>>> distinct_candidates(pop, 3).shape
(2, 2, 2)
"""

from __future__ import annotations

import numpy as np

from pac_host.coverage import expand, simulate
from pac_host.model.table import side, strength

CHOICES = ("paper", "informative", "rows")
DEFAULT_CANDIDATES = 16  # distinct turn cycles from the top of the CGA's population
TEACHING_ROWS = 8  # with "rows": candidates that swap in one uncertain row each


def distinct_candidates(cga_pop: np.ndarray, n: int) -> np.ndarray:
    """Up to ``n`` distinct turn cycles from the population (best first), the best excluded."""
    out, seen = [], {cga_pop[0].tobytes()}
    for tc in cga_pop[1:]:
        key = tc.tobytes()
        if key not in seen:
            seen.add(key)
            out.append(tc)
            if len(out) == n:
                break
    return np.array(out, dtype=cga_pop.dtype).reshape((len(out),) + cga_pop.shape[1:])


def disagreement(models: np.ndarray, candidates: np.ndarray, budget: int, effects=()
                 ) -> np.ndarray:
    """Standard deviation over the models of each candidate's predicted coverage fitness."""
    cov = simulate(models, candidates, budget, effects)
    return cov.fitness.astype(np.float64).std(axis=0)


def row_uncertainty(candidates: np.ndarray, row_var: np.ndarray, budget: int) -> np.ndarray:
    """Posterior variance summed over the distinct rows each candidate walks (rows it never
    reaches in ``budget`` gait cycles do not count)."""
    ids, still = expand(candidates, budget)
    out = np.zeros(len(candidates))
    for k in range(len(candidates)):
        if not still[k]:
            out[k] = row_var[np.unique(ids[k])].sum()
    return out


def teaching_variants(best: np.ndarray, row_var: np.ndarray, k: int) -> np.ndarray:
    """The best turn cycle (9, 2) with one pair's gait cycle swapped for one of the ``k`` rows
    of most posterior variance ``row_var`` (32,) that it does not use, one variant a row: the
    pair of the same turn side and nearest strength takes the row, with its repetitions, so
    the variant stays close to the sweep and walks the row for as long as the pair did.

    >>> best = np.array([[3, 5], [20, 2]] + [[3, 0]] * 7)
    >>> row_var = np.zeros(32); row_var[[1, 30]] = [2.0, 1.0]
    >>> teaching_variants(best, row_var, 2)[:, :2].tolist()
    [[[1, 5], [20, 2]], [[3, 5], [30, 2]]]
    """
    ids = best[:, 0]
    rows = [int(r) for r in np.argsort(-row_var, kind="stable") if not (ids == r).any()][:k]
    out = []
    for r in rows:
        far = np.abs(strength(ids) - strength(r)) + 16 * (side(ids) != side(r))
        y = best.copy()
        y[int(np.argmin(far)), 0] = r
        out.append(y)
    return np.array(out, dtype=best.dtype).reshape((len(out),) + best.shape)


def choose(
    best: np.ndarray,
    perturbed: np.ndarray,
    cga_pop: np.ndarray,
    models: np.ndarray,
    row_var: np.ndarray,
    budget: int,
    effects=(),
    n_tests: int = 2,
    n_candidates: int = DEFAULT_CANDIDATES,
    hopeful: np.ndarray | None = None,
    teach: int = 0,
) -> np.ndarray:
    """The best turn cycle and the ``n_tests`` candidates the models disagree on most.

    ``perturbed`` are the paper's perturbations (candidates too); ``row_var`` (32,) is the
    posterior variance of each row (summed over components), the tie-break. ``hopeful``, when
    the best was chosen for being sure on every model (a search pooled over the posterior):
    the best turn cycle on the model alone, which takes the first test after the best, so the
    rows the model is hopeful about get tested. ``teach``: that many
    :func:`teaching_variants` of the best join the candidates.
    """
    if hopeful is not None and hopeful.tobytes() != best.tobytes() and n_tests > 0:
        rest = choose(best, perturbed, cga_pop[~(cga_pop == hopeful).all(axis=(1, 2))],
                      models, row_var, budget, effects, n_tests - 1, n_candidates,
                      teach=teach)
        return np.concatenate([rest[:1], hopeful[None], rest[1:]])
    cands = np.concatenate([perturbed, distinct_candidates(cga_pop, n_candidates),
                            teaching_variants(best, row_var, teach)])
    _, keep = np.unique(cands.reshape(len(cands), -1), axis=0, return_index=True)
    keep = np.sort(keep)
    keep = keep[[cands[k].tobytes() != best.tobytes() for k in keep]]
    cands = cands[keep]
    if len(cands) == 0:
        return np.concatenate([best[None], perturbed[:n_tests]])
    spread = disagreement(models, cands, budget, effects)
    unknown = row_uncertainty(cands, row_var, budget)
    order = np.lexsort((-unknown, -spread))  # most disagreement first, then least evidence
    picked = cands[order[:n_tests]]
    while len(picked) < n_tests:  # too few distinct candidates: fall back on the paper's
        picked = np.concatenate([picked, perturbed[len(picked) - n_tests:][:1]])
    return np.concatenate([best[None], picked])
