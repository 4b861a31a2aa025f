"""Gaussian kernel density estimates for the shot-cycle model (our own, numpy only).

Why not `scipy.stats.gaussian_kde`: the model needs leave-one-out cross-validated bandwidths,
the peak density for its rejection rule, a mode by mean shift, and sampling from a numpy
Generator; all four are a few lines on the same whitened-distance matrix.

The kernel covariance is ``factor**2 * Sigma`` with Sigma the data covariance (floored at
``min_std**2`` along every principal axis, so identical points still give a proper density),
as in Scott's rule; only the scalar `factor` is chosen, by maximising the leave-one-out
log-likelihood over a geometric grid (`FACTOR_GRID`). Above `LOO_MAX_POINTS` points the
likelihood is computed on an evenly strided subset (deterministic).

Rejection rule (Vid2Player): a sample whose density is below `reject_below` (a tenth) of the
peak density is drawn again. The peak is estimated as the largest density at the data points,
where a Gaussian mixture's maxima lie in practice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FACTOR_GRID = np.geomspace(0.05, 1.5, 24)
LOO_MAX_POINTS = 1200
REJECT_BELOW = 0.1
MAX_REJECTION_ROUNDS = 50


@dataclass(frozen=True)
class KDE:
    """A fitted Gaussian KDE. `points` (n, d); kernel covariance `cov` (d, d)."""

    points: np.ndarray
    cov: np.ndarray
    factor: float
    peak: float

    @property
    def dim(self) -> int:
        return self.points.shape[1]

    def pdf(self, x) -> np.ndarray:
        """Density at `x` (m, d) or (d,) -> (m,)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if self.dim == 1 and x.shape[0] == 1 and x.shape[1] != 1:
            x = x.T
        return _pdf(x, self.points, self.cov)

    def sample(self, rng: np.random.Generator, n: int = 1, reject_below: float = REJECT_BELOW,
               centres: np.ndarray | None = None, accept=None) -> np.ndarray:
        """`n` draws (n, d), redrawing any below `reject_below` * `peak` density.

        `centres` (boolean mask over `points`) restricts the kernels drawn from, and `accept`
        (draws -> boolean mask) adds a condition, so a draw can be conditioned on, e.g., the
        examples that landed in and on landing in itself. After `MAX_REJECTION_ROUNDS` rounds
        the remaining draws are kernel centres (real examples)."""
        chol = np.linalg.cholesky(self.cov)
        pool = self.points if centres is None else self.points[np.asarray(centres, bool)]
        if len(pool) == 0:
            raise ValueError("no kernel centres to sample from")
        out = np.empty((n, self.dim))
        todo = np.arange(n)
        for _ in range(MAX_REJECTION_ROUNDS):
            centre = pool[rng.integers(len(pool), size=todo.size)]
            draw = centre + rng.standard_normal((todo.size, self.dim)) @ chol.T
            ok = self.pdf(draw) >= reject_below * self.peak
            if accept is not None:
                ok &= np.asarray(accept(draw), bool)
            out[todo[ok]] = draw[ok]
            todo = todo[~ok]
            if todo.size == 0:
                return out
        out[todo] = pool[rng.integers(len(pool), size=todo.size)]
        return out

    def mode(self, n_iter: int = 50) -> np.ndarray:
        """The highest mode: mean shift started from the densest data point."""
        x = self.points[int(np.argmax(self.pdf(self.points)))].copy()
        inv = np.linalg.inv(self.cov)
        for _ in range(n_iter):
            d = self.points - x
            w = np.exp(-0.5 * np.einsum("ij,jk,ik->i", d, inv, d))
            new = w @ self.points / w.sum()
            if np.max(np.abs(new - x)) < 1e-6:
                return new
            x = new
        return x


def _pdf(x: np.ndarray, points: np.ndarray, cov: np.ndarray) -> np.ndarray:
    d = points.shape[1]
    chol = np.linalg.cholesky(cov)
    # Whitened differences: |L^-1 (x - p)|^2 is the Mahalanobis distance under `cov`.
    zx = np.linalg.solve(chol, x.T).T
    zp = np.linalg.solve(chol, points.T).T
    sq = _sq_dists(zx, zp)
    norm = (2.0 * math.pi) ** (d / 2.0) * float(np.prod(np.diag(chol)))
    return np.exp(-0.5 * sq).mean(axis=1) / norm


def _sq_dists(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    sq = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(sq, 0.0)


def data_covariance(points: np.ndarray, min_std: float) -> np.ndarray:
    """Covariance of `points` (n, d) with every principal variance floored at `min_std`**2
    (so a cell of identical or collinear examples still has a proper kernel)."""
    d = points.shape[1]
    cov = np.atleast_2d(np.cov(points, rowvar=False)) if len(points) > 1 else np.zeros((d, d))
    lam, vec = np.linalg.eigh(cov)
    lam = np.maximum(lam, float(min_std) ** 2)
    return (vec * lam) @ vec.T


def loo_log_likelihood(points: np.ndarray, base_cov: np.ndarray,
                       factors: np.ndarray = FACTOR_GRID) -> np.ndarray:
    """Mean leave-one-out log-likelihood of `points` for each kernel `factor` (covariance
    factor**2 * `base_cov`). Needs at least 2 points."""
    n, d = points.shape
    if n < 2:
        raise ValueError(f"leave-one-out needs at least 2 points, got {n}")
    if n > LOO_MAX_POINTS:
        points = points[np.linspace(0, n - 1, LOO_MAX_POINTS).astype(int)]
        n = len(points)
    chol = np.linalg.cholesky(base_cov)
    z = np.linalg.solve(chol, points.T).T
    sq = _sq_dists(z, z)
    np.fill_diagonal(sq, np.inf)
    log_norm = 0.5 * d * math.log(2.0 * math.pi) + float(np.sum(np.log(np.diag(chol))))
    out = np.empty(len(factors))
    for k, f in enumerate(factors):
        # log-sum-exp per row, without the point itself (its distance is inf)
        a = -0.5 * sq / (f * f)
        top = a.max(axis=1)
        s = np.log(np.exp(a - top[:, None]).sum(axis=1)) + top
        ll = s - math.log(n - 1) - log_norm - d * math.log(f)
        out[k] = float(np.mean(np.maximum(ll, -1e3)))  # an isolated point costs a bounded amount
    return out


def fit_kde(points, min_std: float = 0.05,
            factors: np.ndarray = FACTOR_GRID) -> KDE:
    """KDE of `points` ((n, d) or (n,)) with the leave-one-out cross-validated factor (Scott's
    factor n^(-1/(d+4)) for fewer than 3 points, where leave-one-out says little)."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = pts[:, None]
    pts = pts[np.isfinite(pts).all(axis=1)]
    n, d = pts.shape
    if n == 0:
        raise ValueError("cannot fit a KDE to no points")
    base = data_covariance(pts, min_std)
    if n < 3:
        factor = float(n ** (-1.0 / (d + 4)))
    else:
        factor = float(factors[int(np.argmax(loo_log_likelihood(pts, base, factors)))])
    cov = factor * factor * base
    peak = float(np.max(_pdf(pts, pts, cov)))
    return KDE(points=pts, cov=cov, factor=factor, peak=peak)
