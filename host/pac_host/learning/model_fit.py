"""Whole-table model correction from observed steps: structure first, then rows by evidence.

PAL's model GA corrects only the gait cycles the tests used; every other row stays as wrong as
it started. This module corrects the whole table from every step observed so far, in two layers:

1. **Structure.** The effects library of DESIGN.md section 3 is fitted to the observed runs
   with the gap diagnosis (:func:`pac_host.diagnose.diagnose`: forward selection judged on
   held-out runs). An effect seen on the used rows (a turn shift, a turn scale, a yaw bias)
   moves every row. Table-level effects are folded into the rows; sequence and world effects
   (transition, battery sag, floor slope) stay effects of the model.
2. **Rows by evidence.** What the structure leaves is a per-row offset, estimated by Bayesian
   linear regression (ridge): the model's predicted step is linear in the rows for fixed
   sequence effects, so each observed step is one linear equation in the offsets. The prior
   (offsets ~ N(0, tau^2) per component) is fitted to the data (empirical Bayes: the spread of
   the offsets of rows with strong evidence), so on a robot the structure explains, unused rows
   stay at the structure, and on a robot with independent row errors they stay uncertain.
   Where the offsets are smooth across gait cycles of similar turn strength (an effect outside
   the library), the smooth prior of :mod:`pac_host.learning.row_prior` carries them to unused rows.
   Optionally (``refine=True``) the sequence and world effects' parameters are first fitted
   again on every run with the rows (:func:`refine_effects`): the selection estimates them on
   the latest runs with held-out splits, and a transition off by 0.01 leaves the rows a misfit
   that decides which blocks a 200-cycle path covers.

The result is a Gaussian posterior over the table: a mean (the CGA's model), a covariance per
component, and the evidence (observed steps) of each row. Samples of it are a population of
models whose disagreement says which tests would teach most
(:mod:`pac_host.learning.test_selection`).

>>> import numpy as np
>>> from pac_host.model import measured_table, shifted_table
>>> from pac_host.learning.testing import SimulatedRobot
>>> tests = np.array([[[12, 20], [3, 8], [19, 6]]])
>>> res = SimulatedRobot(shifted_table()).run_tests(tests)
>>> obs = [Observed(expand_ids(tests[0], 200), res[0].poses)]
>>> post = correct(measured_table(), obs, np.random.default_rng(0))
>>> post.evidence[[3, 12, 19, 5]].tolist()   # steps seen per row; row 5 was never used
[48, 120, 32, 0]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from pac_host.coverage import expand
from pac_host.coverage.gaps import seen_stretches
from pac_host.diagnose import Run, split_runs
from pac_host.diagnose.noise import StepNoiseFit, estimate_step_noise
from pac_host.diagnose.pipeline import select_effects
from pac_host.diagnose.residuals import Batch, batch_of, predicted_moves, row_design, step_residuals
from pac_host.errors import InputError
from pac_host.learning import row_prior
from pac_host.learning.model_ga import DEFAULT_SCALE
from pac_host.model.effects import EFFECT_SPECS, Effect, effective_rows
from pac_host.model.table import N_IDS, GaitTable

STRUCTURES = ("none", "effects")
MIN_RUNS_FOR_EFFECTS = 2  # the diagnosis holds whole runs out: it needs at least two
STRUCTURE_RUNS = 9  # the effects are fitted on the latest runs (three punctuations): the
# diagnosis's cost grows with the steps, and three punctuations hold 600 steps
HOLDOUT_FRACTION = 0.3
MIN_ROWS_SPLIT = 4  # a table-level effect is judged on held-out rows: at least 3 + 1 rows
MIN_ROWS_FOR_PRIOR = 4  # rows with strong evidence needed to fit the prior's spread
STRONG_EVIDENCE = 10  # steps for a row's offset to count in the prior's spread
TAU_FLOOR = 0.02  # the prior's spread never falls below this share of DEFAULT_SCALE
SIGMA_FLOOR = 1e-3  # smallest step noise used (noise-free simulated robots)


@dataclass(frozen=True)
class Observed:
    """One observed test: the gait ids executed and the observed poses (start pose first; a
    NaN pose for a gait cycle the observer could not see: a gap)."""

    gait_ids: np.ndarray  # (n,)
    poses: np.ndarray  # (n + 1, 3)
    cycles_since_power_on: int = 0


def seen_parts(observed: Observed) -> tuple[Observed, ...]:
    """An observed test whose path has gaps (NaN poses: gait cycles the observer could not
    see) as the stretches seen end to end, each from a seen pose; a step next to a gap is
    dropped. A test without gaps is itself."""
    poses = np.asarray(observed.poses, dtype=np.float64)
    if np.isfinite(poses).all():
        return (observed,)
    return tuple(Observed(np.asarray(observed.gait_ids)[a:b], poses[a:b + 1],
                          observed.cycles_since_power_on + a)
                 for a, b in seen_stretches(poses))


def expand_ids(turn_cycle: np.ndarray, budget: int) -> np.ndarray:
    """The gait ids a turn cycle executes in ``budget`` gait cycles (empty if it stands still)."""
    ids, still = expand(np.asarray(turn_cycle)[None], budget)
    return ids[0] if not still[0] else ids[0, :0]


@dataclass(frozen=True)
class Posterior:
    """A Gaussian belief about the robot's table: mean rows, per-component covariance of the
    rows' offsets from the structure, evidence per row, and the model's effects."""

    mean: np.ndarray  # (32, 3)
    cov: np.ndarray  # (3, 32, 32): per component F, T, dH
    evidence: np.ndarray  # (32,) observed steps per row
    effects: tuple[Effect, ...]  # sequence and world effects the model keeps
    selected: tuple[Effect, ...]  # every effect the structure fit selected
    tau: np.ndarray  # (3,) the prior's spread of row offsets
    sigma: np.ndarray  # (3,) step noise per component

    @property
    def sd(self) -> np.ndarray:
        """Posterior standard deviation of each row and component (32, 3)."""
        return np.sqrt(np.stack([np.diag(c) for c in self.cov], axis=1))

    def sample(self, size: int, rng: np.random.Generator,
               rows: np.ndarray | None = None) -> np.ndarray:
        """``size`` tables drawn from the posterior (model 0 is the mean). With ``rows``, only
        those rows are drawn (from their joint conditional); the others stay at the mean."""
        out = np.broadcast_to(self.mean, (size, N_IDS, 3)).copy()
        idx = np.arange(N_IDS) if rows is None else np.asarray(rows, dtype=np.int64)
        if size <= 1 or len(idx) == 0:
            return out
        z = rng.normal(size=(size - 1, len(idx), 3))
        for c in range(3):
            cov = self.cov[c][np.ix_(idx, idx)]
            chol = np.linalg.cholesky(cov + 1e-12 * np.eye(len(idx)))
            out[1:, idx, c] += z[..., c] @ chol.T
        return out


def _runs(observed: Sequence[Observed]) -> list[Run]:
    """The tests as runs of the diagnosis, ``t<i>``; a test with gaps as its stretches seen
    end to end (:func:`seen_parts`), ``t<i>/<k>``."""
    out = []
    for i, whole in enumerate(observed):
        parts = seen_parts(whole)
        for k, o in enumerate(parts):
            if len(o.gait_ids) > 0:
                out.append(Run(f"t{i}" if o is whole else f"t{i}/{k}",
                               np.asarray(o.poses[0], dtype=np.float64), np.asarray(o.gait_ids),
                               np.asarray(o.poses[1:], dtype=np.float64),
                               int(o.cycles_since_power_on)))
    return out


def _latest(runs: Sequence[Run], n: int) -> list[Run]:
    """The runs of the latest ``n`` tests (a test seen with gaps is several runs, t<i>/<k>)."""
    tests = set(list(dict.fromkeys(r.run_id.split("/")[0] for r in runs))[-n:])
    return [r for r in runs if r.run_id.split("/")[0] in tests]


def step_noise(observed: Sequence[Observed]) -> StepNoiseFit | None:
    """The robot's step noise per component, with its interval, from every observed test
    (:func:`pac_host.diagnose.noise.estimate_step_noise`; None: no repeated steps yet)."""
    return estimate_step_noise(_runs(observed))


def fit_structure(base: GaitTable, runs: Sequence[Run], rng: np.random.Generator
                  ) -> tuple[Effect, ...]:
    """Effects of the library the latest runs show on top of ``base`` (none before two runs).

    Table-level effects must carry over to rows no test used, so they are judged by held-out
    rows, not held-out runs (the three tests of a punctuation share their rows): the runs are
    cut into stretches of one repeated gait cycle and the stretches of about 30% of the rows
    are held out. Then, so that wrong rows do not pass for a sequence or world effect, those
    effects are selected on whole runs of the table whose used rows are fitted beside each
    effect, their estimation error counted in the held-out runs' noise
    (:mod:`pac_host.diagnose.fitted_rows`). Every run's start pose is taken as unknown (its
    first step is left out): a robot placed by hand starts at a nominal pose, or one read by
    another instrument than the steps' poses, and that one error passed for a drift or a sag.
    """
    runs = [_free_start(r) for r in _latest(runs, STRUCTURE_RUNS) if r.n >= 2]
    if len(runs) < MIN_RUNS_FOR_EFFECTS:
        return ()
    have = {e.name for e in base.effects}
    table_lib = [n for n, sp in EFFECT_SPECS.items() if sp.stage == "table" and n not in have]
    seq_lib = [n for n, sp in EFFECT_SPECS.items() if sp.stage != "table" and n not in have]
    found: tuple[Effect, ...] = ()
    fit_s, hold_s = _split_by_rows(_stretches(runs), rng)
    if table_lib and fit_s and hold_s:
        found = select_effects(base, fit_s, hold_s, table_lib)
    if not seq_lib:
        return found
    table_fx, seq_fx = _split_effects(tuple(base.effects) + found)
    fit, hold = split_runs(runs, HOLDOUT_FRACTION, rng)
    free = _rows_only(GaitTable(effective_rows(base.rows, table_fx), (), base.name), fit, seq_fx)
    more = select_effects(free, fit, hold, seq_lib, rows_fitted=True)
    batch = batch_of(runs)
    keep = [e for e in more if _moves_anything(free, batch, e)]
    return found + tuple(keep)


def _free_start(run: Run) -> Run:
    """``run`` from its first observed pose on: its start pose and first step left out."""
    return Run(run.run_id, run.poses[0], run.gait_cycles[1:], run.poses[1:],
               run.cycles_since_power_on + 1)


def _moves_anything(table: GaitTable, batch, effect: Effect) -> bool:
    """False for an effect fitted to nothing (noise-free runs let a null effect through)."""
    a = predicted_moves(table.rows, batch, table.effects)
    b = predicted_moves(table.rows, batch, tuple(table.effects) + (effect,))
    return bool(np.abs(a - b).max() > 1e-9)


def _stretches(runs: Sequence[Run]) -> list[Run]:
    """Each stretch of one gait cycle repeated, as a run of its own; the first step after a
    change of gait is left out (a transition would blend it with the gait before)."""
    out = []
    for r in runs:
        ids, poses = r.gait_cycles, r.all_poses()
        start = 0
        for i in range(1, len(ids) + 1):
            if i < len(ids) and ids[i] == ids[start]:
                continue
            lo = start + (start > 0)
            if i - lo >= 2:
                out.append(Run(f"{r.run_id}s{lo}", poses[lo], ids[lo:i], poses[lo + 1: i + 1],
                               r.cycles_since_power_on + lo))
            start = i
    return out


def _split_by_rows(stretches: list[Run], rng: np.random.Generator
                   ) -> tuple[list[Run], list[Run]]:
    """(fitting, held-out) stretches, about ``HOLDOUT_FRACTION`` of the rows held out; both
    empty when fewer than ``MIN_ROWS_SPLIT`` rows were seen."""
    rows = np.unique([int(s.gait_cycles[0]) for s in stretches]) if stretches else []
    if len(rows) < MIN_ROWS_SPLIT:
        return [], []
    k = max(1, round(HOLDOUT_FRACTION * len(rows)))
    hold = set(rng.permutation(rows)[:k].tolist())
    return ([s for s in stretches if int(s.gait_cycles[0]) not in hold],
            [s for s in stretches if int(s.gait_cycles[0]) in hold])


def _rows_only(base: GaitTable, runs: Sequence[Run], seq_fx: Sequence[Effect]) -> GaitTable:
    """``base`` (no table-level effects) with each row the runs use set to its least-squares
    fit to their steps under ``seq_fx``, which the result keeps."""
    used, offsets, _ = _row_least_squares(base.rows, batch_of(runs), seq_fx)
    rows = base.rows.copy()
    rows[used] += offsets
    return GaitTable(rows, tuple(seq_fx), base.name)


def _row_least_squares(rows: np.ndarray, batch: Batch, seq_fx: Sequence[Effect]
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rows the steps use (mask), their least-squares offsets from ``rows`` under
    ``seq_fx``, and the residual (steps, 3) those offsets leave."""
    mask = batch.mask.ravel()
    resid = step_residuals(rows, batch, seq_fx).reshape(-1, 3)[mask]
    design = row_design(batch, seq_fx).reshape(-1, N_IDS)[mask]
    used = design.any(axis=0)
    offsets = np.linalg.pinv(design[:, used]) @ resid
    return used, offsets, resid - design[:, used] @ offsets


def _split_effects(effects: Sequence[Effect]) -> tuple[list[Effect], list[Effect]]:
    table = [e for e in effects if EFFECT_SPECS[e.name].stage == "table"]
    return table, [e for e in effects if EFFECT_SPECS[e.name].stage != "table"]


def structure_due(n_runs: int, selected_at: int | None) -> bool:
    """Whether to select the effects again with ``n_runs`` runs observed, the last selection
    having been made with ``selected_at`` (None: never): while the window of the latest
    :data:`STRUCTURE_RUNS` runs is still filling, and then each time it holds only runs the
    last selection did not see. (A selection costs seconds; one per window loses nothing the
    window could show.)"""
    return selected_at is None or n_runs <= STRUCTURE_RUNS or n_runs - selected_at >= STRUCTURE_RUNS


def refine_effects(rows: np.ndarray, batch: Batch, effects: Sequence[Effect],
                   scale: Sequence[float] = DEFAULT_SCALE) -> tuple[Effect, ...]:
    """``effects`` (sequence and world effects) with their continuous parameters fitted again,
    jointly with the rows, to every observed step in ``batch``.

    Variable projection: for given parameters the prediction is linear in the rows, so each
    candidate is judged by the residual (per component in units of ``scale``) left after the
    rows the runs use take their least-squares values; SciPy's bounded least squares (trust
    region) starts at the given values. The result is kept only where it fits better, so a
    flat or noisy objective leaves the effects as they were. Deterministic: no RNG.

    >>> import numpy as np
    >>> from pac_host.diagnose import Run
    >>> from pac_host.model import measured_table
    >>> from pac_host.model.effects import Effect
    >>> from pac_host.learning.testing import SimulatedRobot
    >>> truth = GaitTable(measured_table().rows, (Effect("transition", {"alpha": 0.3}),))
    >>> tc = np.array([[[12, 3], [3, 2], [19, 4]]])
    >>> res = SimulatedRobot(truth).run_tests(tc)[0]
    >>> run = Run("t0", res.poses[0], expand_ids(tc[0], 200), res.poses[1:], 0)
    >>> guess = (Effect("transition", {"alpha": 0.31}),)
    >>> round(refine_effects(truth.rows, batch_of([run]), guess)[0].params["alpha"], 4)
    0.3
    """
    effects = tuple(effects)
    free = [(i, p) for i, e in enumerate(effects) for p in EFFECT_SPECS[e.name].params
            if not p.integer]
    if not free:
        return effects
    weight = 1.0 / np.asarray(scale, dtype=np.float64)

    def with_values(x: np.ndarray) -> tuple[Effect, ...]:
        params = [dict(e.params) for e in effects]
        for (i, p), v in zip(free, x, strict=True):
            params[i][p.name] = float(min(max(v, p.lo), p.hi))
        return tuple(Effect(e.name, q) for e, q in zip(effects, params, strict=True))

    def misfit(x: np.ndarray) -> np.ndarray:
        return (_row_least_squares(rows, batch, with_values(x))[2] * weight).ravel()

    lo = np.array([p.lo for _, p in free])
    hi = np.array([p.hi for _, p in free])
    x0 = np.array([effects[i].params[p.name] for i, p in free], dtype=np.float64)
    inside = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))  # trf starts inside
    res = least_squares(misfit, inside, bounds=(lo, hi), method="trf")
    before = float(np.sum(misfit(x0) ** 2))
    return with_values(res.x) if 2 * res.cost < before else effects


def correct(
    base: GaitTable,
    observed: Sequence[Observed],
    rng: np.random.Generator,
    structure: str = "effects",
    prior_sd: Sequence[float] = DEFAULT_SCALE,
    selected: tuple[Effect, ...] | None = None,
    refine: bool = False,
) -> Posterior:
    """The posterior over the table given every observed test (see the module docstring).

    ``structure`` "none" skips the effects fit (rows by evidence around ``base`` alone);
    ``selected`` gives the effects instead of selecting them again (see
    :func:`structure_due`); ``refine`` fits the sequence and world effects' parameters again
    on every run, with the rows (:func:`refine_effects`).
    """
    if structure not in STRUCTURES:
        raise InputError(f"unknown structure {structure!r}; use one of {', '.join(STRUCTURES)}")
    runs = _runs(observed)
    if structure != "effects":
        selected = ()
    elif selected is None:
        selected = fit_structure(base, runs, rng)
    table_fx, seq_fx = _split_effects(tuple(base.effects) + selected)
    struct_rows = effective_rows(base.rows, table_fx)
    prior = np.asarray(prior_sd, dtype=np.float64)
    if not runs:
        cov = np.stack([np.eye(N_IDS) * s * s for s in prior])
        return Posterior(struct_rows, cov, np.zeros(N_IDS, dtype=np.int64), tuple(seq_fx),
                         selected, prior, np.full(3, np.nan))
    batch = batch_of(runs)
    if refine and seq_fx:
        seq_fx = list(refine_effects(struct_rows, batch, seq_fx, prior))
    mask = batch.mask.ravel()
    resid = step_residuals(struct_rows, batch, seq_fx).reshape(-1, 3)[mask]
    design = row_design(batch, seq_fx).reshape(-1, N_IDS)[mask]  # (steps, 32)
    evidence = np.bincount(batch.ids.ravel()[mask], minlength=N_IDS)
    sigma, tau, mean, cov = _ridge(design, resid, evidence, prior)
    return Posterior(struct_rows + mean, cov, evidence, tuple(seq_fx), selected, tau, sigma)


def _ridge(design: np.ndarray, resid: np.ndarray, evidence: np.ndarray, prior: np.ndarray):
    """Per component: noise sd, prior spread (empirical Bayes), posterior mean and covariance
    of the 32 row offsets."""
    gram = design.T @ design
    used = evidence > 0
    strong = evidence >= STRONG_EVIDENCE
    sigma, tau = np.empty(3), np.empty(3)
    means, covs = np.zeros((N_IDS, 3)), np.empty((3, N_IDS, N_IDS))
    for c in range(3):
        # least squares on the used rows alone: the offsets the data say, and the noise left
        sub = np.ix_(used, used)
        ls = np.linalg.pinv(gram[sub]) @ (design[:, used].T @ resid[:, c])
        rss = float(np.sum((resid[:, c] - design[:, used] @ ls) ** 2))
        dof = max(len(resid) - int(used.sum()), 1)
        sigma[c] = max(np.sqrt(rss / dof), SIGMA_FLOOR)
        off = np.zeros(N_IDS)
        off[used] = ls
        if strong.sum() >= MIN_ROWS_FOR_PRIOR:
            # spread of true offsets: observed spread less what the noise adds
            noise_var = sigma[c] ** 2 * np.diag(np.linalg.pinv(gram[sub]))
            strong_in_used = strong[used]
            spread = np.mean(off[strong] ** 2) - np.mean(noise_var[strong_in_used])
            tau[c] = max(np.sqrt(max(spread, 0.0)), TAU_FLOOR * prior[c])
        else:
            tau[c] = prior[c]
        xty = design.T @ resid[:, c]
        smooth = None
        if strong.sum() >= MIN_ROWS_FOR_PRIOR:  # offsets shared by similar gait cycles?
            smooth = row_prior.smooth_prior(gram, xty, sigma[c], prior[c],
                                            floor=TAU_FLOOR * prior[c])
        if smooth is not None:
            means[:, c], covs[c] = row_prior.posterior(smooth, gram, xty, sigma[c])
            continue
        prec = gram / sigma[c] ** 2 + np.eye(N_IDS) / tau[c] ** 2
        covs[c] = np.linalg.inv(prec)
        covs[c] = 0.5 * (covs[c] + covs[c].T)
        means[:, c] = covs[c] @ xty / sigma[c] ** 2
    return sigma, tau, means, covs
