"""Single-window inference without PyTorch's per-call overhead.

A streaming estimator calls a model once per control cycle with one window.
PyTorch spends most of such a call in dispatch (about 250 us for a 2-layer LSTM
on one core here); the arithmetic is a few thousand multiply-adds. This module
copies a trained network's weights into float64 arrays once and evaluates them
with small numba-compiled kernels (MLP, conv, LSTM), a few microseconds per call.
Results agree with the PyTorch path to float32 rounding (tested).
"""
from __future__ import annotations

import numpy as np
from numba import njit
from torch import nn

from .nets import ConvNet, LSTMNet, MLPNet

_ACT = {nn.ReLU: 1, nn.Tanh: 2}


@njit(cache=True)
def _lstm_layer(x, w_ih, w_hh, b):
    """One LSTM layer over x (T, F); gate order i, f, g, o (PyTorch). Returns (T, H)."""
    T = x.shape[0]
    H = w_hh.shape[1]
    pre = x @ w_ih.T
    h = np.zeros(H)
    c = np.zeros(H)
    out = np.empty((T, H))
    for t in range(T):
        g = pre[t] + b + w_hh @ h
        for j in range(H):
            i_g = 1.0 / (1.0 + np.exp(-g[j]))
            f_g = 1.0 / (1.0 + np.exp(-g[H + j]))
            c_g = np.tanh(g[2 * H + j])
            o_g = 1.0 / (1.0 + np.exp(-g[3 * H + j]))
            c[j] = f_g * c[j] + i_g * c_g
            h[j] = o_g * np.tanh(c[j])
        out[t] = h
    return out


@njit(cache=True)
def _conv_relu_flat(x, w, b):
    """Conv1d ('valid') over x (T, F) with w (C, F, k), ReLU, flattened channel-major."""
    T = x.shape[0]
    C, F, k = w.shape
    Tout = T - k + 1
    out = np.empty(C * Tout)
    for ch in range(C):
        for t in range(Tout):
            s = b[ch]
            for f in range(F):
                for j in range(k):
                    s += w[ch, f, j] * x[t + j, f]
            out[ch * Tout + t] = s if s > 0.0 else 0.0
    return out


@njit(cache=True)
def _dense_stack(h, weights, biases, acts):
    """Fully connected layers; acts[i]: 0 none, 1 relu, 2 tanh."""
    for i in range(len(weights)):
        h = weights[i] @ h + biases[i]
        if acts[i] == 1:
            h = np.maximum(h, 0.0)
        elif acts[i] == 2:
            h = np.tanh(h)
    return h


class FastNet:
    """A float64 copy of an MLPNet, ConvNet or LSTMNet for single windows (L, F) -> (n_out,)."""

    def __init__(self, net: nn.Module):
        f64 = lambda t: np.ascontiguousarray(t.detach().cpu().double().numpy())  # noqa: E731
        self.kind = type(net).__name__
        if isinstance(net, LSTMNet):
            self.lstm = [(f64(m.weight_ih_l0), f64(m.weight_hh_l0), f64(m.bias_ih_l0 + m.bias_hh_l0)) for m in net.lstms]
        elif isinstance(net, ConvNet):
            self.conv = (f64(net.conv.weight), f64(net.conv.bias))
        elif not isinstance(net, MLPNet):
            raise TypeError(f"no fast path for {type(net).__name__}")
        weights, biases, acts = [], [], []
        mods = list(net.head)
        for i, m in enumerate(mods):
            if isinstance(m, nn.Linear):
                weights.append(f64(m.weight))
                biases.append(f64(m.bias))
                nxt = mods[i + 1] if i + 1 < len(mods) else None
                acts.append(_ACT.get(type(nxt), 0))
        from numba.typed import List

        self.weights, self.biases = List(weights), List(biases)
        self.acts = np.array(acts, dtype=np.int64)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """x: standardized window (L, F) float64; returns the network output (n_out,)."""
        if self.kind == "LSTMNet":
            h = x
            for w_ih, w_hh, b in self.lstm:
                h = _lstm_layer(h, w_ih, w_hh, b)
            h = h[-1]
        elif self.kind == "ConvNet":
            h = _conv_relu_flat(x, *self.conv)
        else:
            h = x[-1]
        return _dense_stack(np.ascontiguousarray(h), self.weights, self.biases, self.acts)


def _softplus(x):
    return np.logaddexp(0.0, x)


def _sigmoid(x):
    return 0.5 * (1.0 + np.tanh(0.5 * x))


class _FastTanhMLP:
    """A tanh MLP of q with its Jacobian d out / d q, by forward-mode differentiation by hand."""

    def __init__(self, seq: nn.Sequential, q_mean, q_std):
        f64 = lambda t: t.detach().cpu().double().numpy()  # noqa: E731
        lin = [m for m in seq if isinstance(m, nn.Linear)]
        self.layers = [(f64(m.weight), f64(m.bias)) for m in lin]
        self.q_mean, self.q_std = f64(q_mean), f64(q_std)

    def __call__(self, q):
        h = (q - self.q_mean) / self.q_std
        J = np.diag(1.0 / self.q_std)
        for W, b in self.layers[:-1]:
            h = np.tanh(W @ h + b)
            J = (1.0 - h * h)[:, None] * (W @ J)
        W, b = self.layers[-1]
        return W @ h + b, W @ J


class FastDeLaN:
    """DeLaN's tau = H qdd + c + g (+ friction) for one sample, derivatives derived by hand.

    The same quantities as :class:`~hybrid_dyn.learn.delan.DeepLagrangianNetwork`, which gets
    them by automatic differentiation; equality of the two is a test of both.
    With J = dL/dq: dH/dq_k = J_k L^T + L J_k^T, c = (sum_k dH/dq_k qd_k) qd - 1/2 [qd^T dH/dq_k qd]_k,
    g = dV/dq.
    """

    def __init__(self, delan, friction=None):
        self.nv, self.eps = delan.nv, float(delan.eps)
        self.l_net = _FastTanhMLP(delan.l_net, delan.q_mean, delan.q_std)
        self.v_net = _FastTanhMLP(delan.v_net, delan.q_mean, delan.q_std)
        self.place = delan.place.double().numpy()
        self.v_scale = float(delan.torque_scale)
        self.friction = None
        if friction is not None:
            self.friction = tuple(t.detach().double().numpy() for t in (friction.phi1, friction.phi2, friction.phi3))

    def terms(self, q, qd, qdd) -> dict:
        nv = self.nv
        out, J = self.l_net(q)
        vec = np.concatenate([_softplus(out[:nv]), out[nv:]])
        dvec = np.concatenate([_sigmoid(out[:nv])[:, None] * J[:nv], J[nv:]])  # (n_l, nv)
        L = (vec @ self.place).reshape(nv, nv)
        dL = (dvec.T @ self.place).reshape(nv, nv, nv)  # dL[k] = dL / dq_k
        H = L @ L.T + self.eps * np.eye(nv)
        LdL = np.einsum("kij,lj->kil", dL, L)  # dL_k L^T
        dH = LdL + LdL.transpose(0, 2, 1)
        c = np.einsum("kij,k,j->i", dH, qd, qd) - 0.5 * np.einsum("i,kij,j->k", qd, dH, qd)
        g = self.v_scale * self.v_net(q)[1][0]
        return {"tau": H @ qdd + c + g, "H": H, "c": c, "g": g}

    def __call__(self, q, qd, qdd) -> np.ndarray:
        tau = self.terms(q, qd, qdd)["tau"]
        if self.friction is not None:
            p1, p2, p3 = self.friction
            tau = tau + p1 * (_sigmoid(p2 * (qd + p3)) - _sigmoid(p2 * p3))
        return tau
