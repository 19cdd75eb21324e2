"""The noise floor: how much of the residual is noise that no effect can remove.

Two kinds of noise. The tracker adds independent Gaussian noise to x, y (sigma_p, cm) and h
(sigma_h, deg) of every observed pose (DESIGN.md section 3); a gait cycle's observed move is a
difference of two observed poses, so that noise is shared by consecutive steps. A real robot
also varies from step to step by itself (step noise: q_p cm on F and T, q_h deg on dH,
independent per gait cycle), which accumulates along a run. Both are the floor: no effect of
the library removes them, and the likelihood (:mod:`.likelihood`) must know both, or a robot's
own step variability would look like unexplained structure.

Method: segments of repeated identical steps, no model needed. Within a segment of one gait
cycle repeated (its first step dropped when it follows a gait change), the true moves are the
same under every table effect and ``transition``, so the observed moves minus the segment's
mean are noise alone (plus a tiny part of a slow drift such as ``battery_sag``). The noise of a
segment of L steps is MA(1) plus white: for dH, covariance ``sigma_h^2 T(1) + q_h^2 I`` with
``T(rho)`` tridiagonal (2 on the diagonal, -rho beside it); for each of F and T,
``sigma_p^2 T(cos dH) + (q_p^2 + sigma_h^2 |(F, T)|^2 / 2) I`` (the frame turns by dH between
steps; heading noise enters the position through (T, -F) in radians, once per step). The
centred lag-0 and lag-1 sums of squares have expectations linear in the two unknown
variances (``tr(C Sigma)`` and ``tr(C U C Sigma)``, C the centring matrix, U the shift), summed
over all segments and solved as a 2 x 2 system; a variance that comes out negative is set to 0
and the other refitted. Heading first, then position (whose white part needs sigma_h).

:func:`estimate_noise` then maximises the restricted likelihood of the segments (each one's
mean unknown) from there: the DST-I basis diagonalises every ``T(rho)``, so the likelihood is a
sum over the segments' sine coefficients, and it uses every lag where the moments use two. The
step noise shows at long lags (over about 2 sigma^2 / q^2 steps it outweighs the tracker's):
with 1 cm / 2 deg of tracker noise the moments lost a step noise of 0.3 cm / 0.6 deg, and the
runs' random walk then looked like structure. Each run's first step is left out there, and its
start pose's noise is estimated apart (:func:`_start_noise`): none when the robot was put
down on a given start pose, the tracker's when the tracker saw it. The second-order white
part of F and T (:mod:`.likelihood`) is in the model, so the step noise is the robot's own.

With fewer than :data:`MIN_REPEATS` usable steps the estimate is flagged unreliable; with no
segments at all it falls back on the rms of the model's one-step residuals (an upper bound).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from pac_host.diagnose.residuals import Batch, batch_of
from pac_host.diagnose.runs import Run
from pac_host.model.step_noise import StepNoise

MIN_REPEATS = 40
FLOOR = 1e-3  # smallest sigma used, so noise-free synthetic data still whitens
STEP_Z = 1.0  # jackknife standard errors a step-noise variance must clear to be kept
START_Z = 3.0  # standard errors the start pose's noise must be below the tracker's to count
TO_RAD2 = (np.pi / 180.0) ** 2


@dataclass(frozen=True)
class NoiseFloor:
    pos_cm: float  # tracker noise on x and y of each pose
    heading_deg: float  # tracker noise on h of each pose
    method: str
    n_used: int
    reliable: bool
    step_cm: float = 0.0  # the robot's own step-to-step variability of F and T
    step_deg: float = 0.0  # ... and of dH
    start_cm: float | None = None  # noise of each run's start pose on x and y, and on h:
    start_deg: float | None = None  # 0 for a given start, None for the tracker's (observed)

    def start_var(self) -> np.ndarray:
        """The start pose's noise variances (x, y, h): :attr:`start_cm` and
        :attr:`start_deg`, the tracker's where None."""
        p = self.pos_cm if self.start_cm is None else self.start_cm
        h = self.heading_deg if self.start_deg is None else self.start_deg
        return np.array([p**2, p**2, h**2])

    def to_json(self) -> dict:
        out = {"pos_cm": round(self.pos_cm, 4), "heading_deg": round(self.heading_deg, 4),
               "step_cm": round(self.step_cm, 4), "step_deg": round(self.step_deg, 4),
               "method": self.method, "n_used": self.n_used, "reliable": self.reliable}
        sv = np.sqrt(self.start_var())
        return {**out, "start_cm": round(float(sv[0]), 4), "start_deg": round(float(sv[2]), 4)}


def segments(batch: Batch, min_len: int = 3) -> list[tuple[int, int, int]]:
    """(run, first step, length) of maximal stretches of one gait cycle repeated, without the
    first step after a gait change (which ``transition`` may blend), at least ``min_len``."""
    out = []
    for r, n in enumerate(batch.lengths):
        ids = batch.ids[r, :n]
        cuts = np.flatnonzero(np.diff(ids)) + 1
        starts = np.concatenate([[0], cuts])
        ends = np.concatenate([cuts, [n]])
        for a, b in zip(starts, ends, strict=True):
            a = a + 1 if a > 0 else a  # a gait change: drop the blended first step
            if b - a >= min_len:
                out.append((r, int(a), int(b - a)))
    return out


@lru_cache(maxsize=256)
def _coefficients(n: int) -> tuple[float, float, float, float]:
    """Traces for a segment of n steps: tr(C), tr(C S), tr(CUC), tr(CUC S), with C the
    centring matrix, U the shift and S = U + U^T; T(rho) = 2 I - rho S."""
    c = np.eye(n) - 1.0 / n
    u = np.eye(n, k=1)
    sh = u + u.T
    cuc = c @ u @ c
    return (float(np.trace(c)), float(np.trace(c @ sh)), float(np.trace(cuc)),
            float(np.trace(cuc @ sh)))


def _solve(s0: float, s1: float, a: np.ndarray) -> tuple[float, float]:
    """Non-negative (x, y) with E[s0] = a00 x + a01 y, E[s1] = a10 x + a11 y."""
    try:
        x, y = np.linalg.solve(a, [s0, s1])
    except np.linalg.LinAlgError:
        x, y = -1.0, -1.0
    if x >= 0 and y >= 0:
        return float(x), float(y)
    b = np.array([s0, s1])
    fits = []
    for col in (0, 1):  # one variance at zero: least squares for the other
        v = max(float(a[:, col] @ b / (a[:, col] @ a[:, col])), 0.0)
        fits.append((float(((a[:, col] * v - b) ** 2).sum()), col, v))
    _, col, v = min(fits)
    return (v, 0.0) if col == 0 else (0.0, v)


def _moments(batch: Batch, segs: list) -> tuple[np.ndarray, ...]:
    """Per segment: heading sums (S, 2) and design (S, 2, 2); position sums (S, 2), design
    (S, 2, 2) and the heading-coupling coefficients (S, 2) of the white part."""
    obs = batch.observed
    k = len(segs)
    sh, ah = np.zeros((k, 2)), np.zeros((k, 2, 2))
    sp, ap, wp = np.zeros((k, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2))
    for j, (r, i0, n) in enumerate(segs):
        x = obs[r, i0 : i0 + n]
        xc = x - x.mean(axis=0)
        tr_c, tr_cs, tr_cuc, tr_cucs = _coefficients(n)
        sh[j] = (xc[:, 2] ** 2).sum(), (xc[:-1, 2] * xc[1:, 2]).sum()
        ah[j] = [[2 * tr_c - tr_cs, tr_c], [2 * tr_cuc - tr_cucs, tr_cuc]]
        rho = float(np.cos(np.radians(x[:, 2].mean())))
        ft2 = float((x[:, 0] ** 2 + x[:, 1] ** 2).mean()) * TO_RAD2
        sp[j] = (xc[:, :2] ** 2).sum(), (xc[:-1, :2] * xc[1:, :2]).sum()
        ap[j] = [[2 * (2 * tr_c - rho * tr_cs), 2 * tr_c],
                 [2 * (2 * tr_cuc - rho * tr_cucs), 2 * tr_cuc]]
        wp[j] = tr_c * ft2, tr_cuc * ft2
    return sh, ah, sp, ap, wp


def _fit(sh, ah, sp, ap, wp) -> tuple[float, float, float, float]:
    """(var_h, q_h^2, var_p, q_p^2) from moment sums over a set of segments."""
    var_h, qh = _solve(*sh.sum(axis=0), ah.sum(axis=0))
    s = sp.sum(axis=0) - var_h * wp.sum(axis=0)
    var_p, qp = _solve(s[0], s[1], ap.sum(axis=0))
    return var_h, qh, var_p, qp


def _fit_with_errors(m: tuple[np.ndarray, ...]) -> tuple[tuple[float, ...], np.ndarray]:
    """:func:`_fit` over all segments' moments ``m`` and the jackknife standard errors (4,) of
    its four variances (segments in up to 20 groups; inf with fewer than 3)."""
    fit = _fit(*m)
    k = len(m[0])
    groups = np.arange(k) % min(20, k)
    g = int(groups.max()) + 1
    if g < 3:
        return fit, np.full(4, np.inf)
    jack = np.array([_fit(*(a[groups != j] for a in m)) for j in range(g)])
    return fit, np.sqrt((g - 1) / g * ((jack - jack.mean(axis=0)) ** 2).sum(axis=0))


def _solve_fixed(b: np.ndarray, a: np.ndarray, with_step: bool) -> tuple[float, float]:
    """Both variances, or the tracker variance alone (step variance 0) by least squares."""
    if with_step:
        return _solve(b[0], b[1], a)
    return max(float(a[:, 0] @ b / (a[:, 0] @ a[:, 0])), 0.0), 0.0


@lru_cache(maxsize=512)
def _dst(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The orthonormal DST-I basis V (n, n), which diagonalises every ``T(rho)`` (eigenvalues
    ``2 - 2 rho cos_k``), the cosines cos_k (n,) and the coefficients of the constant, V^T 1."""
    k = np.arange(1, n + 1)
    v = np.sqrt(2.0 / (n + 1)) * np.sin(np.pi * np.outer(k, k) / (n + 1))
    return v, np.cos(np.pi * k / (n + 1)), v.sum(axis=0)


@dataclass(frozen=True)
class _Spectra:
    """S segments in the DST basis, padded to the longest (L): coefficients z (S, L, 3) of F,
    T and dH, the eigenvalues of T(rho) (S, L) (rho = cos dH) and of T(1) (S, L), the
    constant's coefficients a (S, L), which entries are real (S, L) and the heading coupling
    of the white part of F and T (S, 2): mean T^2 and F^2 in rad^2 per deg^2."""

    z: np.ndarray
    lam_p: np.ndarray
    lam_h: np.ndarray
    a: np.ndarray
    real: np.ndarray
    couple: np.ndarray


def _spectra(batch: Batch, segs: list) -> _Spectra | None:
    if not segs:
        return None
    obs = batch.observed
    k, top = len(segs), max(n for _, _, n in segs)
    z, a = np.zeros((k, top, 3)), np.zeros((k, top))
    lam_p, lam_h = np.ones((k, top)), np.ones((k, top))
    real = np.zeros((k, top), dtype=bool)
    couple = np.zeros((k, 2))
    for j, (r, i0, n) in enumerate(segs):
        v, cosk, a[j, :n] = _dst(n)
        x = obs[r, i0 : i0 + n]
        z[j, :n] = v.T @ x
        lam_p[j, :n] = 2.0 - 2.0 * np.cos(np.radians(x[:, 2].mean())) * cosk
        lam_h[j, :n] = 2.0 - 2.0 * cosk
        real[j, :n] = True
        couple[j] = (x[:, 1] ** 2).mean() * TO_RAD2, (x[:, 0] ** 2).mean() * TO_RAD2
    return _Spectra(z, lam_p, lam_h, a, real, couple)


def _reml_terms(sp: _Spectra, comp: int, tracker: float, step: float, white: float,
                info: bool = False) -> tuple[float, np.ndarray]:
    """Restricted negative log-likelihood of one component of the segments (their means
    unknown) and its gradient (2,) in (tracker, step) variance, or with ``info`` their Fisher
    information (2, 2); ``white``: the tracker's heading variance, for F and T (its part in
    their white noise)."""
    # F and T: the heading noise turns the position noise too, a white 2 var_p var_h rad^2
    lam = sp.lam_h if comp == 2 else sp.lam_p + 2.0 * white * TO_RAD2
    extra = white * sp.couple[:, comp, None] if comp < 2 else 0.0
    z, a2 = sp.z[..., comp], sp.a**2
    d = np.where(sp.real, tracker * lam + step + extra, 1.0)  # the covariance's eigenvalues
    ia, iz = (a2 / d).sum(axis=1), (sp.a * z / d).sum(axis=1)
    grads = (np.where(sp.real, lam, 0.0), sp.real.astype(np.float64))
    if info:
        out = np.empty((2, 2))
        for i in range(2):
            for j in range(2):
                gi, gj = grads[i], grads[j]
                out[i, j] = 0.5 * float(((gi * gj / d**2).sum(axis=1)
                                         - 2.0 / ia * (a2 * gi * gj / d**3).sum(axis=1)
                                         + (a2 * gi / d**2).sum(axis=1)
                                         * (a2 * gj / d**2).sum(axis=1) / ia**2).sum())
        return 0.0, out
    nll = 0.5 * float(np.log(d).sum() + np.log(ia).sum()
                      + ((z**2 / d).sum(axis=1) - iz**2 / ia).sum())
    grad = np.empty(2)
    for i, g in enumerate(grads):
        ga = (a2 * g / d**2).sum(axis=1)
        grad[i] = 0.5 * float((g / d).sum() - (ga / ia).sum()
                              - (z**2 * g / d**2).sum()
                              + (2 * iz * (sp.a * z * g / d**2).sum(axis=1) / ia).sum()
                              - (iz**2 * ga / ia**2).sum())
    return nll, grad


def _reml(sp: _Spectra, comp: tuple[int, ...], start: tuple[float, float],
          white: float = 0.0, with_step: bool = True) -> tuple[float, float, float]:
    """(tracker, step variance, standard error of the step variance) maximising the restricted
    likelihood of components ``comp`` over all segments, the tracker variance >= FLOOR^2 and
    the step variance >= 0 (held at 0 when not ``with_step``): Fisher scoring, halving steps
    that do not lower the objective, the step variance fixed at its bound while the gradient
    pushes it there."""

    def terms(x: np.ndarray, info: bool = False):
        parts = [_reml_terms(sp, c, x[0], x[1], white, info) for c in comp]
        return sum(t[0] for t in parts), sum(t[1] for t in parts)

    lo = FLOOR**2
    x = np.array([max(start[0], lo), max(start[1], 0.0) if with_step else 0.0])
    f, g = terms(x)
    for _ in range(100):
        fisher = terms(x, info=True)[1]
        free = [0, 1] if with_step and not (x[1] <= 0.0 and g[1] > 0.0) else [0]
        step = np.zeros(2)
        try:
            step[free] = -np.linalg.solve(fisher[np.ix_(free, free)], g[free])
        except np.linalg.LinAlgError:
            break
        t = 1.0
        while t > 1e-6:
            xn = np.maximum(x + t * step, [lo, 0.0])
            fn, gn = terms(xn)
            if fn <= f + 1e-12 * abs(f):
                break
            t /= 2.0
        else:
            break
        done = np.all(np.abs(xn - x) <= 1e-8 * (np.abs(x) + x.sum()))
        x, f, g = xn, fn, gn
        if done:
            break
    info = terms(x, info=True)[1]
    try:
        se = float(np.sqrt(max(np.linalg.inv(info)[1, 1], 0.0)))
    except np.linalg.LinAlgError:
        se = float("inf")
    return float(x[0]), float(x[1]), se


def _start_noise(batch: Batch, var_h: float, qh: float, var_p: float, qp: float
                 ) -> float | None:
    """How noisy each run's start pose is, as a share of the tracker's variance: about 0 for
    a robot put down exactly on a given start pose, 1 for a start the tracker observed; None
    when no run's first gait cycle repeats.

    Within a run's first stretch of one gait cycle the moves are equal, so the poses after
    the start lie on a line (a circle's arc, turned to the frame of each move) and point back
    to the start pose: the contrast of the stretch's moves that is blind to their common value
    and carries the start pose's noise with weight one, with the least variance under the
    floor (generalised least squares), has a variance known but for the start pose's part. The
    share is the weighted least-squares fit of the squared contrasts over the runs and
    components. A share below 1 is taken only when it is :data:`START_Z` standard errors
    below it (else 1, observed): an observed start taken as exact pins the whole run to a
    wrong pose (a transition or a sag to the selection in 3 of 100 effect-free structure fits
    of 6 runs), a given start taken as observed only leaves one pose free."""
    d2, base, coef = [], [], []
    obs = batch.observed
    turn = 2.0 * var_p * var_h * TO_RAD2  # the second-order white part of F and T
    for r, n in enumerate(batch.lengths):
        ids = batch.ids[r, :n]
        length = int(np.argmax(ids != ids[0])) if (ids != ids[0]).any() else int(n)
        if length < 2:
            continue
        x = obs[r, :length]
        rho = float(np.cos(np.radians(x[:, 2].mean())))
        ones, first = np.ones(length), np.eye(length)[0]
        for c in range(3):
            if c == 2:
                var, white, start = var_h, qh, var_h
            else:  # F carries T's heading coupling, T carries F's
                other = x[:, 1 - c] ** 2 * TO_RAD2
                var, white = var_p, qp + turn + var_h * float(other.mean())
                start = var_p + var_h * float(other[0])
            off = -(rho if c < 2 else 1.0) * var
            cov = (np.diag(np.full(length, 2 * var + white)) + np.diag(np.full(length - 1, off), 1)
                   + np.diag(np.full(length - 1, off), -1))
            cov[0, 0] -= start  # the floor without the start pose's noise
            g = np.linalg.solve(cov, np.stack([ones, first], axis=1))
            m = np.linalg.inv(np.stack([ones, first], axis=1).T @ g)
            a = g @ m[:, 1]  # blind to the common move, weight one on the start pose
            d2.append(float(a @ x[:, c]) ** 2)
            base.append(float(m[1, 1]))
            coef.append(start)
    if not d2:
        return None
    d2, base, coef = np.array(d2), np.array(base), np.array(coef)
    wt = 1.0 / (base + 0.5 * coef) ** 2  # 1 / var(d^2), up to a factor, halfway
    share = float((wt * (d2 - base) * coef).sum() / (wt * coef**2).sum())
    # its standard error were the start observed (var d^2 = 2 E[d^2]^2, E[d^2] = base + coef)
    se = float(np.sqrt((wt**2 * coef**2 * 2 * (base + coef) ** 2).sum()) / (wt * coef**2).sum())
    if share < 1.0 and 1.0 - share < START_Z * se:
        return 1.0  # not clearly less noisy than the tracker: observed
    return max(share, 0.0)


def estimate_noise(batch: Batch, residuals: np.ndarray | None = None) -> NoiseFloor:
    """Estimate the noise floor from repeated identical steps of the runs in ``batch``.

    The moments start the restricted likelihood (module docstring), which gives the floor. A
    step-noise variance is kept only when it exceeds :data:`STEP_Z` standard errors (from the
    likelihood's Fisher information; jackknife over segments in up to 20 groups when no
    segment is long enough for it): telling two noise kinds apart costs precision, and a step
    noise that is an artefact of few data would mask slow effects. The start pose's noise:
    :func:`_start_noise`. ``residuals`` (R, N, 3), the model's one-step residuals, are only
    used by the fallback.
    """
    segs = segments(batch)
    n_used = sum(n for _, _, n in segs)
    if segs:
        m = _moments(batch, segs)
        (var_h, qh, var_p, qp), se = _fit_with_errors(m)
        # the restricted likelihood, each run's first step left out (its start pose may be
        # exact): every lag, where the moments use two
        spectra = _spectra(batch, [(r, i0 + (i0 == 0), n - (i0 == 0)) for r, i0, n in segs
                                   if n - (i0 == 0) >= 3])
        if spectra is not None:
            var_h, qh, se_h = _reml(spectra, (2,), (var_h, qh))
            if qh <= STEP_Z * se_h:
                var_h, qh, _ = _reml(spectra, (2,), (var_h, 0.0), with_step=False)
            var_p, qp, se_p = _reml(spectra, (0, 1), (var_p, qp), var_h)
            if qp <= STEP_Z * se_p:
                var_p, qp, _ = _reml(spectra, (0, 1), (var_p, 0.0), var_h, with_step=False)
        elif qh <= STEP_Z * se[1] or qp <= STEP_Z * se[3]:
            # refit with the step noise that is not clear set to zero
            keep_h, keep_p = qh > STEP_Z * se[1], qp > STEP_Z * se[3]
            var_h, qh = _solve_fixed(m[0].sum(axis=0), m[1].sum(axis=0), keep_h)
            s = m[2].sum(axis=0) - var_h * m[4].sum(axis=0)
            var_p, qp = _solve_fixed(s, m[3].sum(axis=0), keep_p)
        pos, head = max(np.sqrt(var_p), FLOOR), max(np.sqrt(var_h), FLOOR)
        share = _start_noise(batch, var_h, qh, var_p, qp)
        start = (None, None) if share is None else (pos * np.sqrt(share),
                                                    head * np.sqrt(share))
        return NoiseFloor(pos, head, "repeated_identical_steps", n_used, n_used >= MIN_REPEATS,
                          float(np.sqrt(qp)), float(np.sqrt(qh)), *start)
    if residuals is None:
        raise ValueError("no repeated steps: residuals are needed for the fallback estimate")
    flat = residuals[batch.mask]
    pos = float(np.sqrt((flat[:, :2] ** 2).mean() / 2.0))  # each component: 2 sigma_p^2
    head = float(np.sqrt((flat[:, 2] ** 2).mean() / 2.0))
    return NoiseFloor(max(pos, FLOOR), max(head, FLOOR), "residual_rms_upper_bound",
                      int(batch.mask.sum()), False)


def _period(ids: np.ndarray) -> int | None:
    """The shortest period of a run's gait cycles (a turn cycle walked in a loop), if the run
    holds at least three periods."""
    n = len(ids)
    for length in range(1, n // 3 + 1):
        if np.array_equal(ids[length:], ids[:-length]):
            return length
    return None


def loop_heading_noise(runs: Sequence[Run], var_h: float, var_h_se: float
                       ) -> tuple[float, float] | None:
    """The step noise variance of dH (deg^2) and its standard error from whole loops of the
    turn cycle each run walks: (estimate, se), or None when no run holds four loops.

    A robot that repeats its moves turns by the same amount over every loop of its turn cycle,
    whatever its table and sequence effects; step noise adds ``L q_h^2`` to each loop of L gait
    cycles, and that sum over a loop stands far clearer above the tracker's ``sigma_h`` than a
    single step's ``q_h^2`` does (a repeated-steps stretch is often too short to show it: 0.5
    deg under 1 deg of tracker noise was not clear after 4000 steps). Third differences across
    loops, ``h[i+3L] - 3 h[i+2L] + 3 h[i+L] - h[i]`` at every phase i, cancel every move the
    robot repeats and a drift growing linearly over the run (``battery_sag``); their expected
    square is ``6 L q_h^2 + 20 sigma_h^2``. ``var_h`` (the tracker's sigma_h^2, from the
    repeated steps) and its standard error ``var_h_se`` are taken as given and their error
    carried into the result's; the loops' own part is a jackknife over runs.
    """
    num, den, count = [], [], []
    for r in runs:
        length = _period(np.asarray(r.gait_cycles))
        if length is None:
            continue
        h = r.poses[:, 2]
        ok = np.isfinite(h)
        h = np.degrees(np.unwrap(np.radians(np.where(ok, h, 0.0))))
        i = np.arange(length - 1, len(h) - 3 * length)  # the first loop's end on: observed
        if len(i) == 0:
            continue
        third = h[i + 3 * length] - 3 * h[i + 2 * length] + 3 * h[i + length] - h[i]
        good = ok[i] & ok[i + length] & ok[i + 2 * length] & ok[i + 3 * length]
        if not good.any():
            continue
        num.append(float((third[good] ** 2).sum()))
        den.append(6.0 * length * int(good.sum()))
        count.append(int(good.sum()))
    if not num:
        return None
    num_a, den_a, n_a = np.array(num), np.array(den), np.array(count)
    est = (num_a.sum() - 20.0 * var_h * n_a.sum()) / den_a.sum()
    k = len(num_a)
    if k < 3:
        return None
    jack = np.array([(num_a.sum() - num_a[j] - 20.0 * var_h * (n_a.sum() - n_a[j]))
                     / (den_a.sum() - den_a[j]) for j in range(k)])
    se_loops = np.sqrt((k - 1) / k * ((jack - jack.mean()) ** 2).sum())
    se_tracker = 20.0 * n_a.sum() / den_a.sum() * var_h_se
    se = float(np.hypot(se_loops, se_tracker)) if np.isfinite(var_h_se) else np.inf
    return float(est), se if se > 0 else np.inf


Z95 = 1.959964  # the two-sided 95% normal quantile
MIN_STEP_CM = 0.01  # step noise below these moves no path off a block: taken as none
MIN_STEP_DEG = 0.05
CLEAR_Z = 3.29  # one-sided 1 in 2000: step noise to decide by, not a noisy tracker's chance


@dataclass(frozen=True)
class StepNoiseFit:
    """The robot's step noise estimated from observed runs (:func:`estimate_step_noise`):
    per component F, T (cm, pooled: the estimator sees them alike) and dH (deg), the point
    estimate ``value`` (3,), the jackknife standard error of its variance ``var_se`` (3,) and
    the 95% interval (3, 2) on the deviation; ``n_used`` repeated steps behind it."""

    value: np.ndarray
    var_se: np.ndarray
    interval: np.ndarray
    n_used: int

    @property
    def noise(self) -> StepNoise:
        """The estimate as a :class:`StepNoise`, uniform over gait cycles."""
        return StepNoise(self.value)

    def clear(self) -> bool:
        """Whether the robot is noisy on this evidence: some component's variance more than
        :data:`CLEAR_Z` standard errors above zero and its deviation above the
        :data:`MIN_STEP_CM` / :data:`MIN_STEP_DEG` floor. A noise-free robot gives False, a
        noisy tracker alone almost never True (the 95% interval alone would, one time in
        twenty): decisions change only on noise that is there."""
        floor = np.array([MIN_STEP_CM, MIN_STEP_CM, MIN_STEP_DEG])
        return bool(((self.value**2 > CLEAR_Z * self.var_se) & (self.value >= floor)).any())

    def decided(self) -> StepNoise:
        """The noise to decide with: the estimate when :meth:`clear`, else none."""
        return self.noise if self.clear() else StepNoise(np.zeros(3))

    def to_json(self) -> dict:
        """``{"F": {"value", "interval"}, "T": ..., "dH": ..., "n_used", "clear"}``."""
        out: dict = {c: {"value": round(float(v), 4),
                         "interval": [round(float(lo), 4), round(float(hi), 4)]}
                     for c, v, (lo, hi) in zip(("F", "T", "dH"), self.value, self.interval,
                                               strict=True)}
        return {**out, "n_used": self.n_used, "clear": self.clear()}


def estimate_step_noise(runs: Sequence[Run], start_observed: bool = False
                        ) -> StepNoiseFit | None:
    """The robot's step noise from observed runs: :func:`estimate_noise`'s moments of repeated
    identical steps (which tell the tracker's noise, shared by consecutive steps, from the
    robot's own, independent per step), without its keep-or-drop test, with a 95% interval;
    for dH combined (by inverse variance) with :func:`loop_heading_noise`, the heading noise
    summed over whole loops of each run's turn cycle, which a tracker noisier than the robot
    hides far less.

    No model is needed: within a stretch of one gait cycle repeated every table and sequence
    effect moves the robot alike, and a model's residuals would count its row errors as noise.
    Each run's first step is left out unless ``start_observed`` (a start pose put down by hand
    is not an observation of the tracker). The interval is on the variance, value +- 1.96
    jackknife standard errors clipped at zero, then its square root; None: no repeated steps.

    >>> from pac_host.diagnose.runs import Run
    >>> ids = np.array([12] * 30)
    >>> poses = np.cumsum(np.tile([[0.0, 10.0, 0.0]], (30, 1)), axis=0)
    >>> fit = estimate_step_noise([Run(str(i), np.zeros(3), ids, poses) for i in range(4)])
    >>> fit.value.tolist(), fit.clear()
    ([0.0, 0.0, 0.0], False)
    """
    if not start_observed:
        runs = [Run(r.run_id, r.poses[0], r.gait_cycles[1:], r.poses[1:],
                    r.cycles_since_power_on + 1) for r in runs if r.n >= 2]
    runs = [r for r in runs if r.n > 0]
    if not runs:
        return None
    batch = batch_of(runs)
    segs = segments(batch)
    if not segs:
        return None
    (var_h, qh, _, qp), se = _fit_with_errors(_moments(batch, segs))
    se_h = se[1]
    loops = loop_heading_noise(runs, var_h, se[0])
    if loops is not None and np.isfinite(se_h) and se_h > 0:
        # the steps' and the loops' estimates of dH's variance, by inverse variance
        w = np.array([1.0 / se_h**2, 1.0 / loops[1] ** 2])
        qh, se_h = float(w @ [qh, loops[0]] / w.sum()), float(1.0 / np.sqrt(w.sum()))
    elif loops is not None:
        qh, se_h = loops
    qh = max(qh, 0.0)
    var = np.array([qp, qp, qh])
    var_se = np.array([se[3], se[3], se_h])
    lo = np.sqrt(np.clip(var - Z95 * var_se, 0.0, None))
    hi = np.sqrt(np.clip(var + Z95 * var_se, 0.0, None))
    return StepNoiseFit(np.sqrt(var), var_se, np.stack([lo, hi], axis=1),
                        sum(n for _, _, n in segs))
