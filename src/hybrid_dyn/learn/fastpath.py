"""Single-input-window inference without PyTorch's per-call overhead.

A streaming estimator calls a model once per control cycle with one input window.
PyTorch spends most of such a call in dispatch (about 250 us for a 2-layer LSTM
on one core here); the arithmetic is a few thousand multiply-adds. This module
copies a trained network's weights into float64 arrays once and evaluates them
with small numba-compiled kernels (MLP, conv, LSTM; each kind names its front
here in its declaration, ``learn/nets.py`` and ``learn/delan.py``): a few microseconds for an
MLP, ~25-40 us here for residual-base-momentum's 10-step, 32-unit LSTM input window,
whose exp calls and ~75 k multiply-adds are most of it. Results agree with the
PyTorch path in float64 to 1e-13 (tests/learn/test_fastpath.py).
"""
from __future__ import annotations

import numpy as np
from numba import njit
from torch import nn

from .kind_registry import fast_net_front

_ACT = {nn.ReLU: 1, nn.Tanh: 2}


@njit(cache=True, inline="always")
def _tanh(x):
    """tanh(x) = 2 sigmoid(2x) - 1 through one exp: within 4e-16 of np.tanh (absolute), and about
    3.5x faster than libm's tanh, which set the cost of an LSTM input window (two per unit and step)."""
    return 2.0 / (1.0 + np.exp(-2.0 * x)) - 1.0


@njit(cache=True)
def _lstm_layer(x, w_ih_t, w_hh_t, b):
    """One LSTM layer over x (T, F); gate order i, f, g, o (PyTorch). Returns (T, H).

    w_ih_t (F, 4H) and w_hh_t (H, 4H) are the weights transposed, so that every inner
    loop runs along one contiguous row of the 4H gates: an axpy, which the compiler
    vectorises (a matrix-vector product per step through BLAS costs more in calls
    than in arithmetic at these sizes).
    """
    T, F = x.shape
    H = w_hh_t.shape[0]
    G = 4 * H
    gates = np.empty(G)
    c = np.zeros(H)
    out = np.empty((T, H))
    for t in range(T):
        for j in range(G):
            gates[j] = b[j]
        for f in range(F):
            xf = x[t, f]
            for j in range(G):
                gates[j] += xf * w_ih_t[f, j]
        if t > 0:  # h = 0 before the first step
            for k in range(H):
                hk = out[t - 1, k]
                for j in range(G):
                    gates[j] += hk * w_hh_t[k, j]
        for j in range(H):
            i_g = 1.0 / (1.0 + np.exp(-gates[j]))
            f_g = 1.0 / (1.0 + np.exp(-gates[H + j]))
            c_g = _tanh(gates[2 * H + j])
            o_g = 1.0 / (1.0 + np.exp(-gates[3 * H + j]))
            c[j] = f_g * c[j] + i_g * c_g
            out[t, j] = o_g * _tanh(c[j])
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
def _dense_stack(h, params, layout, acts):
    """Fully connected layers on h (n_in,); returns a fresh (n_out,) array.

    Layer i's weight (n_out, n_in), then its bias (n_out,), lie row-major in the flat
    ``params`` from layout[i] = (offset, n_out, n_in); acts[i]: 0 none, 1 relu, 2 tanh.
    One flat array, not a typed list of matrices: unboxing a list per call cost more
    than the arithmetic of the whole head.
    """
    x = h
    for i in range(layout.shape[0]):
        off, n_out, n_in = layout[i, 0], layout[i, 1], layout[i, 2]
        y = np.empty(n_out)
        for r in range(n_out):
            acc = 0.0
            row = off + r * n_in
            for k in range(n_in):
                acc += params[row + k] * x[k]
            acc += params[off + n_out * n_in + r]
            if acts[i] == 1:
                acc = max(acc, 0.0)
            elif acts[i] == 2:
                acc = np.tanh(acc)
            y[r] = acc
        x = y
    return x


def _f64(t) -> np.ndarray:
    return np.ascontiguousarray(t.detach().cpu().double().numpy())


def mlp_front(parts):
    """The MLP's front: the input window's last row (the head reads the current sample)."""
    return lambda x: x[-1]


def conv_front(parts):
    """The conv net's front: Conv1d ('valid') + ReLU, flattened channel-major (numba)."""
    conv = parts["net"].conv
    w, b = _f64(conv.weight), _f64(conv.bias)
    return lambda x: _conv_relu_flat(x, w, b)


def lstm_front(parts):
    """The LSTM's front: the stacked layers over the input window (numba), the last step's state."""
    layers = [(_f64(m.weight_ih_l0.T), _f64(m.weight_hh_l0.T), _f64(m.bias_ih_l0 + m.bias_hh_l0))
              for m in parts["net"].lstms]  # transposed: see _lstm_layer

    def front(x):
        h = x
        for w_ih_t, w_hh_t, b in layers:
            h = _lstm_layer(h, w_ih_t, w_hh_t, b)
        return h[-1]

    return front


def delan_fast(parts):
    """DeLaN (and its learned friction) for one sample: (q, qd, qdd) -> tau [Nm]."""
    return FastDeLaN(parts["delan"], parts.get("friction"))


class FastNet:
    """A float64 copy of a net kind's network for single input windows (L, F) -> (n_out,): its front as the
    kind declares it (``learn/kind_registry.py``: ``fast``), then the shared FC head (:func:`_dense_stack`)."""

    def __init__(self, net: nn.Module):
        if not hasattr(net, "kind") or not hasattr(net, "head"):
            raise TypeError(f"no fast path for {type(net).__name__}: not a net kind's network (kind, head)")
        self.kind = net.kind
        self._front = fast_net_front(net)
        params, layout, acts = [], [], []  # the head, flat (see _dense_stack)
        mods = list(net.head)
        offset = 0
        for i, m in enumerate(mods):
            if isinstance(m, nn.Linear):
                w, b = _f64(m.weight), _f64(m.bias)
                params += [w.ravel(), b]
                layout.append((offset, w.shape[0], w.shape[1]))
                offset += w.size + b.size
                nxt = mods[i + 1] if i + 1 < len(mods) else None
                acts.append(_ACT.get(type(nxt), 0))
        self.head = np.concatenate(params)
        self.layout = np.array(layout, dtype=np.int64).reshape(-1, 3)
        self.acts = np.array(acts, dtype=np.int64)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """x: standardized input window (L, F) float64; returns the network output (n_out,)."""
        return _dense_stack(np.ascontiguousarray(self._front(x)), self.head, self.layout, self.acts)


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

    The same quantities as :class:`~hybrid_dyn.learn.delan.DeepLagrangianNetwork` (batched,
    in torch), for one sample in numpy; the tests hold both to the autograd oracle.
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
