"""The exact GP's log marginal likelihood and its gradient, for the hyperparameter fit.

The design in full: ``docs/design/learn.md`` (gp_marginal.py).
"""
from __future__ import annotations

import contextlib
import math

import numpy as np
from scipy.linalg import LinAlgError, cho_solve, cholesky
from scipy.linalg.lapack import dpotri
from scipy.optimize import minimize
from scipy.spatial.distance import pdist, squareform

JITTER = 1e-10  # scikit-learn's GaussianProcessRegressor(alpha=1e-10) on K's diagonal


@contextlib.contextmanager
def one_blas_thread():
    """Every BLAS library of the process on one thread for the duration (threadpoolctl, which
    scikit-learn depends on): GP fits are chains of O(n^3) factorizations whose threads, beside
    torch's, spin against each other on a shared 2-core machine."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _inverse_from_cholesky(low: np.ndarray) -> np.ndarray:
    """K^-1 from K's lower Cholesky factor by LAPACK's potri (2n^3/3 flops; a solve against the identity,
    scikit-learn's way, costs 2n^3)."""
    inv, info = dpotri(low, lower=1)
    if info != 0:
        raise LinAlgError(f"potri failed (info {info})")
    inv = np.tril(inv)
    return inv + np.tril(inv, -1).T


def log_marginal_likelihood(theta: np.ndarray, z: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """(lml, d lml / d theta) at theta = [log c, log l_1 .. log l_d, log s], inputs z (n, d), standardized
    targets y (n,). A kernel matrix that is not positive definite gives (-inf, 0), as scikit-learn's."""
    theta = np.asarray(theta, np.float64)
    d = z.shape[1]
    c, ls, s = math.exp(theta[0]), np.exp(theta[1:d + 1]), math.exp(theta[d + 1])
    zs = z / ls
    kf = squareform(np.exp(-0.5 * pdist(zs, metric="sqeuclidean")))
    np.fill_diagonal(kf, 1.0)
    kf *= c
    k = kf.copy()
    k[np.diag_indices_from(k)] += s + JITTER
    try:
        low = cholesky(k, lower=True, check_finite=False)
    except LinAlgError:
        return -np.inf, np.zeros_like(theta)
    alpha = cho_solve((low, True), y, check_finite=False)
    lml = -0.5 * float(y @ alpha) - float(np.log(np.diag(low)).sum()) - 0.5 * len(y) * math.log(2 * math.pi)
    w = np.outer(alpha, alpha) - _inverse_from_cholesky(low)
    m = w * kf
    grad = np.empty_like(theta)
    grad[0] = 0.5 * m.sum()
    grad[1:d + 1] = (zs ** 2).T @ m.sum(1) - np.sum(zs * (m @ zs), axis=0)  # 1/2 x 2 (M symmetric)
    grad[d + 1] = 0.5 * s * np.trace(w)
    return lml, grad


def fit_hyperparameters(z: np.ndarray, y: np.ndarray, constant_bounds, length_scale_bounds, noise_bounds,
                        noise_init: float) -> tuple[float, np.ndarray, float, float]:
    """Maximum marginal likelihood (c, l (d,), s, lml) on inputs z (n, d) and targets y (n,) [any unit:
    standardized here, as scikit-learn's ``normalize_y``], from c = 1, s = ``noise_init`` and l = 1 or sqrt(d)."""
    y = np.asarray(y, np.float64)
    std = y.std()
    y = (y - y.mean()) / (std if std > 0 else 1.0)
    d = z.shape[1]
    bounds = np.log([constant_bounds] + [length_scale_bounds] * d + [noise_bounds])

    def objective(theta):
        lml, grad = log_marginal_likelihood(theta, z, y)
        return -lml, -grad

    # Two starts, the better optimum kept: scikit-learn's (l = 1) and l = sqrt(d). At l = 1 on d = 21
    # standardized inputs K is nearly the identity (E|z_i - z_j|^2 = 2d): the length scales' gradients are
    # of order exp(-d), and which basin L-BFGS reaches from there turns on their rounding.
    starts = [np.log(np.r_[1.0, np.full(d, ls), noise_init]) for ls in (1.0, math.sqrt(d))]
    res = min((minimize(objective, theta0, method="L-BFGS-B", jac=True, bounds=bounds) for theta0 in starts),
              key=lambda r: r.fun)
    theta = res.x
    return float(math.exp(theta[0])), np.exp(theta[1:d + 1]), float(math.exp(theta[d + 1])), float(-res.fun)
