"""The compiled kernels of ``KalmanTipForce`` (``analytic/kalman.py``): the time-varying filter's
predict, anchor and update, its batch run, and one streaming step after the dynamics terms."""
from __future__ import annotations

import numpy as np
from numba import njit

from .tip_force import damped_solve3


@njit(cache=True)
def _kf_predict(x, P, qv, dt):  # pragma: no cover (compiled)
    """x <- A x, P <- A P A^T + Q with A = I + dt (e_0 + e_1) e_2^T (each sensor's sum grows by dt F)."""
    for j in range(3):
        x[0, j] += dt * x[2, j]
        x[1, j] += dt * x[2, j]
    for i in range(2):  # rows of A P
        for c in range(3):
            P[i, c] += dt * P[2, c]
    for r in range(3):  # columns of (A P) A^T
        for i in range(2):
            P[r, i] += dt * P[r, 2]
    for i in range(3):
        P[i, i] += qv[i]


@njit(cache=True)
def _kf_anchor(x, P, y, c, rv):  # pragma: no cover (compiled)
    """Sensor c (re)starts: its sum is defined to equal its prediction; its error is its measurement noise."""
    for j in range(3):
        y[c, j] = x[c, j]
    for i in range(3):
        P[c, i] = 0.0
        P[i, c] = 0.0
    P[c, c] = rv[c]


@njit(cache=True)
def _kf_update(x, P, y, c, rv):  # pragma: no cover (compiled)
    """The scalar update by sensor c's sum (R is diagonal: sequential updates are the joint one)."""
    s = P[c, c] + rv[c]
    k = np.empty(3)
    row = np.empty(3)
    for i in range(3):
        k[i] = P[i, c] / s
        row[i] = P[c, i]
    for j in range(3):
        inn = y[c, j] - x[c, j]
        for i in range(3):
            x[i, j] += k[i] * inn
    for a in range(3):
        for b in range(3):
            P[a, b] -= k[a] * row[b]


@njit(cache=True)
def _kf_run(Y, present, P0, qv, rv, dt):  # pragma: no cover (compiled)
    """The filter over sums Y (N, 2, 3) of the sensors ``present`` at every sample, from a start
    (x = 0, P = P0; each sensor anchors at the first sample): the forces (N, 3)."""
    n = Y.shape[0]
    x = np.zeros((3, 3))
    P = P0.copy()
    y = np.zeros((2, 3))
    out = np.empty((n, 3))
    for k in range(n):
        _kf_predict(x, P, qv, dt)
        for c in range(2):
            if present[c]:
                if k == 0:
                    _kf_anchor(x, P, y, c, rv)
                else:
                    for j in range(3):
                        y[c, j] = Y[k, c, j] - Y[0, c, j] + 0.0
        for c in range(2):
            if present[c] and k > 0:
                _kf_update(x, P, y, c, rv)
        for j in range(3):
            out[k, j] = x[2, j]
    return out


@njit(cache=True)
def _fusion_step(x, P, y, last_base, last_joint, since, stats, qv, rv, max_bridge, has_base, h, R3, w, mg3,
                 has_joint, qd, M_upper, g, C, tau, jac, dt, singular_region, max_damping):  # pragma: no cover
    """One predict-update of ``KalmanTipForce`` after the dynamics terms (see ``step_unchecked``).

    x (3, 3): s_base, s_joint, F by axis; P (3, 3) their covariance; y (2, 3): the sensors'
    unexplained momenta; since (2,): calls each sensor has been absent (-1: not seen since the start).
    The joint terms come as Pinocchio gives them: the mass matrix's upper triangle M_upper (what
    computeAllTerms fills), the gravity torque g and the Coriolis matrix C, so p = M qd and
    beta = C^T qd - g are formed here. A sensor back within max_bridge absent calls adds the
    increment over the gap (the trapezoid spanning it); one seen first, or back later, re-anchors.
    The joint increment is projected to the tool by the damped least squares of
    ``tip_force.damped_solve3`` (what ``damped_force_single`` runs).
    """
    _kf_predict(x, P, qv, dt)
    update = np.zeros(2, np.bool_)
    if has_base:
        u = np.empty(3)
        for i in range(3):
            acc = mg3[i]
            for k in range(6):
                acc += R3[i, k] * w[k]
            u[i] = acc
        if 0 <= since[0] <= max_bridge:
            m = since[0] + 1.0
            for i in range(3):
                d = h[i] - last_base[0, i] - (u[i] + last_base[1, i]) * (0.5 * dt * m)
                y[0, i] += d
                stats[0, i] += d
                stats[0, 3 + i] += d * d / m
            stats[0, 6] += 1.0
            stats[0, 7] += m
            update[0] = True
        else:
            _kf_anchor(x, P, y, 0, rv)
        for i in range(3):
            last_base[0, i] = h[i]
            last_base[1, i] = u[i]
        since[0] = 0
    elif since[0] >= 0:
        since[0] += 1
    if has_joint:
        nv = qd.shape[0]
        p = np.empty(nv)
        beta = np.empty(nv)
        for k in range(nv):
            acc = 0.0
            for i in range(nv):
                acc += (M_upper[k, i] if i >= k else M_upper[i, k]) * qd[i]
            p[k] = acc
            acc = -g[k]
            for i in range(nv):
                acc += qd[i] * C[i, k]
            beta[k] = acc
        if 0 <= since[1] <= max_bridge:
            m = since[1] + 1.0
            d = np.empty(nv)
            for k in range(nv):
                d[k] = p[k] - last_joint[0, k] - (tau[k] + beta[k] + last_joint[1, k]) * (0.5 * dt * m)
            a = np.zeros((3, 3))
            bvec = np.zeros(3)
            for i in range(3):
                for k in range(nv):
                    bvec[i] += jac[i, k] * d[k]
                for j in range(3):
                    acc = 0.0
                    for k in range(nv):
                        acc += jac[i, k] * jac[j, k]
                    a[i, j] = acc
            z = damped_solve3(a, bvec, singular_region, max_damping)
            for i in range(3):
                y[1, i] += z[i]
                stats[1, i] += z[i]
                stats[1, 3 + i] += z[i] * z[i] / m
            stats[1, 6] += 1.0
            stats[1, 7] += m
            update[1] = True
        else:
            _kf_anchor(x, P, y, 1, rv)
        for k in range(nv):
            last_joint[0, k] = p[k]
            last_joint[1, k] = tau[k] + beta[k]
        since[1] = 0
    elif since[1] >= 0:
        since[1] += 1
    for c in range(2):
        if update[c]:
            _kf_update(x, P, y, c, rv)
