"""The Gaussian likelihood of one-step residuals, with the noise correlation they really have.

Observed poses carry independent noise, but each observed move is the difference of two observed
poses expressed in the frame of the first one, so the noise of step i and step i + 1 shares the
pose between them. Linearizing the move in the observed poses, the residual vector r of a run is
``r = D e + u`` with e the pose noise (sigma_p on x and y, sigma_h on h), D a sparse matrix of
the frame rotations and u the robot's own step noise (independent per step), giving the
block-tridiagonal covariance ``Sigma = D S D^T + diag(q)``. To second order the heading noise
before a step also turns the step's position noise, a white term of 2 sigma_p^2 sigma_h^2
(radians) on F and T, added to q: tiny, but along a whole run from an exact start the
whitening trusts the long sums where nothing else is left, and without it effect-free runs
showed structure (F about 1.6 in every family of the shape tests). We whiten with the
inverse Cholesky factor, ``w = L^-1 r``: then ``|w|^2`` is the exact (linearized) Gaussian
negative log-likelihood up to a constant, a correctly scaled sum of squares for least squares,
likelihood-ratio tests and BIC. (Treating steps as independent would overstate the information
in smooth effects like ``yaw_bias`` and mis-weight heading against position.)

The factor is taken over each whole run. Its block recursion is the Kalman filter of the
observed poses (true poses a random walk driven by the step noise, the tracker's noise on each
observation), and ``w`` are the filter's standardised innovations: what the steps so far tell
about the noise of the current pose is carried along the whole run. (An earlier version cut
runs into chunks of 64 steps for speed and dropped the pose shared across each border: the
whitened residuals either side of it correlated at -0.7, and on effect-free runs of 40 to 79
gait cycles with an exact start the shape tests flagged 6 cases of 6.) The start pose has its
own noise (:attr:`NoiseFloor.start_cm`, ``start_deg``): none for a robot put down exactly on a
given start pose, the tracker's for an observed one.

The factor is block bidiagonal, so whitening is a forward substitution, 3 x 3 block by block
(compiled with numba: fitting effects whitens thousands of times; a numpy loop over the steps
stands in where numba is missing); the dense ``L^-1`` is kept as the reference it is tested
against.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from pac_host.coverage import kernel as coverage_jit
from pac_host.diagnose.noise import NoiseFloor
from pac_host.diagnose.residuals import Batch

_forward = None  # the compiled forward substitution, made on first use


def _substitute(linv: np.ndarray, sub: np.ndarray, res: np.ndarray, out: np.ndarray) -> None:
    """Solve the block-bidiagonal L w = r run by run: ``w_i = D_i (r_i - S_i w_{i-1})`` with
    D_i the inverse diagonal block and S_i the block below the diagonal. ``linv`` and ``sub``
    are (R, N, 3, 3); ``res`` and ``out`` (M, R, N, 3)."""
    m_, r_, n_, _ = res.shape
    t = np.empty(3)
    for a in range(m_):
        for r in range(r_):
            for i in range(n_):
                for u in range(3):
                    v = res[a, r, i, u]
                    if i:
                        for j in range(3):
                            v -= sub[r, i, u, j] * out[a, r, i - 1, j]
                    t[u] = v
                for u in range(3):
                    v = 0.0
                    for j in range(u + 1):  # D_i is lower triangular
                        v += linv[r, i, u, j] * t[j]
                    out[a, r, i, u] = v


def _substitute_numpy(linv: np.ndarray, sub: np.ndarray, res: np.ndarray) -> np.ndarray:
    """:func:`_substitute` without numba: a loop over the steps, (..., R, N, 3) at once."""
    out = np.empty_like(res)
    for i in range(res.shape[-2]):
        v = res[..., i, :]
        if i:
            v = v - np.einsum("rij,...rj->...ri", sub[:, i], out[..., i - 1, :])
        out[..., i, :] = np.einsum("rij,...rj->...ri", linv[:, i], v)
    return out


def _compiled_forward():
    global _forward
    if _forward is None:
        import numba

        _forward = numba.njit(cache=True, nogil=True)(_substitute)
    return _forward


@dataclass(frozen=True)
class Whitener:
    """Whitening of a batch of R runs of N steps by the block factors of each run's Cholesky
    factor: ``linv`` (the inverse diagonal blocks) and ``sub`` (the blocks below the
    diagonal), each (R, N, 3, 3)."""

    linv: np.ndarray
    sub: np.ndarray

    @property
    def n(self) -> int:  # N, the batch's padded run length
        return self.linv.shape[1]

    @cached_property
    def w(self) -> np.ndarray:
        """The dense whitening matrices ``L^-1`` (R, 3N, 3N), row block by row block: the
        reference the substitution is tested against (memory 72 N^2 bytes a run)."""
        r, c = self.linv.shape[:2]
        w = np.zeros((r, c, 3, 3 * c))
        for i in range(c):
            if i:
                w[:, i, :, : 3 * i] = -(self.linv[:, i] @ self.sub[:, i]) @ \
                    w[:, i - 1, :, : 3 * i]
            w[:, i, :, 3 * i : 3 * i + 3] = self.linv[:, i]
        return w.reshape(r, 3 * c, 3 * c)

    def whiten(self, res: np.ndarray, dense: bool = False) -> np.ndarray:
        """Residuals (..., R, N, 3) -> whitened (..., R, 3N); ``dense``: by the dense
        matrices (the reference) rather than block forward substitution."""
        r, n = self.linv.shape[:2]
        if dense:
            out = (self.w @ res.reshape(res.shape[:-2] + (3 * n,))[..., None])[..., 0]
            return out
        if not coverage_jit.AVAILABLE:
            out = _substitute_numpy(self.linv, self.sub, np.asarray(res, dtype=np.float64))
            return out.reshape(out.shape[:-2] + (3 * n,))
        lead = res.shape[:-3]
        blocks = np.ascontiguousarray(res, dtype=np.float64).reshape((-1, r, n, 3))
        out = np.empty_like(blocks)
        _compiled_forward()(self.linv, self.sub, blocks, out)
        return out.reshape(lead + (r, 3 * n))

    def ssr_per_run(self, res: np.ndarray) -> np.ndarray:
        """Whitened sum of squares per run (..., R)."""
        w = self.whiten(res)
        return np.einsum("...i,...i->...", w, w)


def _chol3(a: np.ndarray) -> np.ndarray:
    """Cholesky factors of symmetric positive definite 3 x 3 matrices (..., 3, 3), closed form
    (no LAPACK call per tiny matrix)."""
    out = np.zeros_like(a)
    l00 = np.sqrt(a[..., 0, 0])
    l10 = a[..., 1, 0] / l00
    l20 = a[..., 2, 0] / l00
    l11 = np.sqrt(a[..., 1, 1] - l10**2)
    l21 = (a[..., 2, 1] - l20 * l10) / l11
    l22 = np.sqrt(a[..., 2, 2] - l20**2 - l21**2)
    out[..., 0, 0], out[..., 1, 0], out[..., 2, 0] = l00, l10, l20
    out[..., 1, 1], out[..., 2, 1], out[..., 2, 2] = l11, l21, l22
    return out


def _inv_lower3(l: np.ndarray) -> np.ndarray:
    """Inverses of lower-triangular 3 x 3 matrices (..., 3, 3)."""
    out = np.zeros_like(l)
    i00, i11, i22 = 1 / l[..., 0, 0], 1 / l[..., 1, 1], 1 / l[..., 2, 2]
    i10 = -l[..., 1, 0] * i00 * i11
    i21 = -l[..., 2, 1] * i11 * i22
    i20 = -(l[..., 2, 0] * i00 + l[..., 2, 1] * i10) * i22
    out[..., 0, 0], out[..., 1, 1], out[..., 2, 2] = i00, i11, i22
    out[..., 1, 0], out[..., 2, 1], out[..., 2, 0] = i10, i21, i20
    return out


def whitener(batch: Batch, noise: NoiseFloor, start_observed: bool = True) -> Whitener:
    """Build the whitening of a batch for a given noise floor.

    Step i's residual is ``P_i e_i + Q_i e_{i+1} + u_i`` (pose noise before and after, step
    noise), so the covariance is block tridiagonal in 3 x 3 blocks: ``A_i = P_i S_i P_i^T +
    Q_i S Q_i^T + diag(q)`` on the diagonal, ``B_i = P_i S Q_{i-1}^T`` below it, with S the
    tracker's noise and S_0 the start pose's (:meth:`NoiseFloor.start_var`). Its block
    Cholesky factor is block bidiagonal; its blocks, step by step along each whole run, are all
    whitening needs. ``start_observed=False``: the start pose is exact whatever the floor says.
    """
    r, n = batch.ids.shape
    rad = np.radians(batch.poses[:, :-1, 2])
    obs = batch.observed
    s, co = np.sin(rad), np.cos(rad)
    to_rad = np.pi / 180.0
    zero, one = np.zeros_like(s), np.ones_like(s)
    p = np.stack([np.stack([-s, -co, obs[..., 1] * to_rad], -1),
                  np.stack([-co, s, -obs[..., 0] * to_rad], -1),
                  np.stack([zero, zero, -one], -1)], -2)  # (r, n, 3, 3)
    q = np.stack([np.stack([s, co, zero], -1), np.stack([co, -s, zero], -1),
                  np.stack([zero, zero, one], -1)], -2)
    var = np.array([noise.pos_cm**2, noise.pos_cm**2, noise.heading_deg**2])
    var_before = np.broadcast_to(var, (r, n, 3)).copy()
    var_before[:, 0] = noise.start_var() if start_observed else 0.0
    a = (p * var_before[..., None, :]) @ p.swapaxes(-1, -2) + (q * var) @ q.swapaxes(-1, -2)
    a += np.diag([noise.step_cm**2, noise.step_cm**2, noise.step_deg**2])  # process noise
    # second order: the frame turns by the heading noise e_h before the step, so the position
    # noise of the step (e_p after minus before) enters as e_h times it: white, like step noise
    a[..., :2, :2] += (np.eye(2) * (var_before[..., 2] * to_rad**2
                                    * (var_before[..., 0] + var[0]))[..., None, None])
    b = np.zeros_like(a)
    b[:, 1:] = (p[:, 1:] * var) @ q[:, :-1].swapaxes(-1, -2)
    valid = batch.mask[..., None, None]
    a = np.where(valid, a, np.eye(3))
    b = np.where(valid & np.roll(valid, 1, axis=1), b, 0.0)
    linvs = np.zeros((r, n, 3, 3))
    subs = np.zeros((r, n, 3, 3))
    linv_prev = None
    for i in range(n):
        if i == 0:
            lii = _chol3(a[:, 0])
        else:
            m = b[:, i] @ linv_prev.swapaxes(-1, -2)
            lii = _chol3(a[:, i] - m @ m.swapaxes(-1, -2))
            subs[:, i] = m
        linvs[:, i] = linv_prev = _inv_lower3(lii)
    return Whitener(linvs, subs)
