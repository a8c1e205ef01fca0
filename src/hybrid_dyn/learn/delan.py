"""Deep Lagrangian Networks (Lutter, Ritter & Peters 2019), written for this toolkit.

The design in full: ``docs/design/learn.md`` (delan.py).
"""
from __future__ import annotations

import math

import torch
from torch import nn
from torch.func import grad, jvp

from .kind_registry import DELAN_PARTS, NETWORK_KINDS, SPACE, NetworkKind, build_net
from .nets import fast_path, glorot_init


def _mlp(n_in: int, hidden: tuple, n_out: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for h in hidden:
        layers += [nn.Linear(n_in, h), nn.Tanh()]
        n_in = h
    layers.append(nn.Linear(n_in, n_out))
    return nn.Sequential(*layers)


class DeepLagrangianNetwork(nn.Module):
    """H(q) = L(q) L(q)^T + eps I and V(q) from two networks; tau by Euler-Lagrange.

    nv: joints. hidden: widths of the hidden layers of both networks.
    eps: the floor on H's eigenvalues [kg m^2]. q_mean / q_std [rad] standardize
    q inside the networks (the derivatives are still w.r.t. physical q).
    torque_scale [Nm]: V's output unit, so g starts at the targets' scale.
    """

    def __init__(self, nv: int, hidden: tuple = (64, 64), eps: float = 1e-3,
                 q_mean=None, q_std=None, torque_scale: float = 1.0):
        super().__init__()
        self.nv = nv
        self.eps = float(eps)
        n_off = nv * (nv - 1) // 2
        self.l_net = _mlp(nv, tuple(hidden), nv + n_off)
        self.v_net = _mlp(nv, tuple(hidden), 1)
        glorot_init(self)
        # Placement of [diagonal, strictly lower entries] into the flattened L.
        rows, cols = torch.tril_indices(nv, nv, -1)
        place = torch.zeros(nv + n_off, nv * nv)
        place[torch.arange(nv), torch.arange(nv) * (nv + 1)] = 1.0
        place[nv + torch.arange(n_off), rows * nv + cols] = 1.0
        self.register_buffer("place", place)
        self.register_buffer("q_mean", torch.zeros(nv) if q_mean is None else torch.as_tensor(q_mean, dtype=torch.float32))
        self.register_buffer("q_std", torch.ones(nv) if q_std is None else torch.as_tensor(q_std, dtype=torch.float32))
        self.register_buffer("torque_scale", torch.tensor(float(torque_scale)))

    # ---- batched maps of q (B, nv); samples are independent, so the gradient of
    # a batch sum is the per-sample gradient (far faster than vmap over grad).
    def _factor(self, out: torch.Tensor) -> torch.Tensor:
        """L (B, nv, nv) from the L-network's output: softplus-positive diagonal, free strictly lower part."""
        return (torch.cat([nn.functional.softplus(out[:, :self.nv]), out[:, self.nv:]], 1)
                @ self.place).reshape(-1, self.nv, self.nv)

    def _mass_from_factor(self, L: torch.Tensor) -> torch.Tensor:
        return L @ L.transpose(1, 2) + self.eps * torch.eye(self.nv, dtype=L.dtype, device=L.device)

    def _mass(self, q: torch.Tensor) -> torch.Tensor:
        return self._mass_from_factor(self._factor(self.l_net((q - self.q_mean) / self.q_std)))

    def _potential(self, q: torch.Tensor) -> torch.Tensor:
        return self.torque_scale * self.v_net((q - self.q_mean) / self.q_std)[:, 0]

    def _forward_with_tangent(self, net: nn.Sequential, q: torch.Tensor, q_dot: torch.Tensor | None):
        """The output of ``net`` on standardized q (B, n_out), its derivative along q_dot,
        d out / dq . q_dot (B, n_out, or None), and each tanh layer's slope 1 - tanh^2 (for :meth:`_pullback`).

        Forward mode by hand with one tangent: a Linear layer maps the tangent by W, a tanh scales it
        by its slope. One tangent costs one more pass, where the full Jacobian would cost nv more.
        """
        h = (q - self.q_mean) / self.q_std
        dh = None if q_dot is None else q_dot / self.q_std
        slopes = []
        for layer in net:
            if isinstance(layer, nn.Tanh):
                h = torch.tanh(h)
                slopes.append(1.0 - h * h)
                dh = None if dh is None else dh * slopes[-1]
            else:  # nn.Linear
                h = layer(h)
                dh = None if dh is None else nn.functional.linear(dh, layer.weight)
        return h, dh, slopes

    def _pullback(self, net: nn.Sequential, slopes: list, v: torch.Tensor) -> torch.Tensor:
        """v^T d out / dq (B, nv) for v (B, n_out): the chain rule run backwards through the layers
        by hand, with the slopes of the forward pass (an explicit expression, not an autograd call)."""
        linears = [layer for layer in net if isinstance(layer, nn.Linear)]
        for layer, slope in zip(reversed(linears[1:]), reversed(slopes)):
            v = (v @ layer.weight) * slope
        return (v @ linears[0].weight) / self.q_std

    def terms(self, q, qd, qdd) -> dict:
        """tau [Nm] (B, nv), H [kg m^2] (B, nv, nv), c and g [Nm] (B, nv), all from the Lagrangian."""
        L, c, g = self._factor_coriolis_gravity(q, qd)
        H = self._mass_from_factor(L)
        return {"tau": (H @ qdd.unsqueeze(2)).squeeze(2) + c + g, "H": H, "c": c, "g": g}

    def _factor_coriolis_gravity(self, q, qd):
        """L(q) (B, nv, nv), c(q, qd) and g(q) [Nm] (B, nv).

        With o the L-network's output, L = place(softplus(o_diag), o_off), so
        dL/dq_k = place(s * do/dq_k) with s = sigmoid(o_diag) on the diagonal entries and 1 elsewhere.
        Then, with u = L^T qd and L_dot = sum_k dL/dq_k qd_k (o's derivative along qd, forward mode):
        H_dot qd = L_dot u + L (L_dot^T qd), and 1/2 d(qd^T H qd)/dq_k = qd^T dL/dq_k u, a
        vector-Jacobian product of the L-network (pulled back by hand); g = dV/dq likewise.
        The 7 x 7 products are written as broadcast sums: batched small matrix products cost more.
        """
        nv = self.nv
        out, out_dot, slopes = self._forward_with_tangent(self.l_net, q, qd)
        s = torch.cat([torch.sigmoid(out[:, :nv]), torch.ones_like(out[:, nv:])], 1)  # d entries / d out
        L = self._factor(out)
        L_dot = ((s * out_dot) @ self.place).reshape(-1, nv, nv)
        u = _t_apply(L, qd)  # L^T qd
        H_dot_qd = _apply(L_dot, u) + _apply(L, _t_apply(L_dot, qd))
        # qd^T dL_k u = sum_m w_m s_m do_m/dq_k, with w the outer product qd u^T read at L's entries.
        w = (qd.unsqueeze(2) * u.unsqueeze(1)).reshape(-1, nv * nv) @ self.place.T
        c = H_dot_qd - self._pullback(self.l_net, slopes, w * s)
        return L, c, self.gravity(q)

    def tau(self, q, qd, qdd) -> torch.Tensor:
        """tau = H qdd + c + g [Nm] (B, nv) without forming H (H qdd = L (L^T qdd) + eps qdd): training's path."""
        L, c, g = self._factor_coriolis_gravity(q, qd)
        return _apply(L, _t_apply(L, qdd)) + self.eps * qdd + c + g

    def terms_autograd(self, q, qd, qdd) -> dict:
        """The same terms as :meth:`terms` by automatic differentiation (the tests' oracle)."""
        H, H_dot = jvp(self._mass, (q,), (qd,))  # H_dot = sum_k dH/dq_k qd_k
        dT_dq = grad(lambda q_: 0.5 * torch.einsum("bi,bij,bj->", qd, self._mass(q_), qd))(q)
        c = torch.einsum("bij,bj->bi", H_dot, qd) - dT_dq
        g = grad(lambda q_: self._potential(q_).sum())(q)
        tau = torch.einsum("bij,bj->bi", H, qdd) + c + g
        return {"tau": tau, "H": H, "c": c, "g": g}

    # ---- batched API, q, qd, qdd: (B, nv) [rad, rad/s, rad/s^2]
    def forward(self, q, qd, qdd) -> torch.Tensor:
        """Joint torques [Nm] (B, nv), rigid body part."""
        return self.tau(q, qd, qdd)

    def mass_matrix(self, q) -> torch.Tensor:
        """H(q) [kg m^2] (B, nv, nv), symmetric positive definite."""
        return self._mass(q)

    def gravity(self, q) -> torch.Tensor:
        """g(q) = dV/dq [Nm] (B, nv)."""
        _, _, slopes = self._forward_with_tangent(self.v_net, q, None)
        return self.torque_scale * self._pullback(self.v_net, slopes, torch.ones_like(q[:, :1]))

    def energy(self, q, qd) -> torch.Tensor:
        """Learned total energy T + V [J] (B,)."""
        T = 0.5 * torch.einsum("bi,bij,bj->b", qd, self._mass(q), qd)
        return T + self._potential(q)

    def forward_dynamics(self, q, qd, tau) -> torch.Tensor:
        """qdd = H^-1 (tau - c - g) (B, nv): the learned system's free or driven motion."""
        t = self.terms(q, qd, torch.zeros_like(q))
        return torch.linalg.solve(t["H"], (tau - t["c"] - t["g"]).unsqueeze(-1)).squeeze(-1)


def _apply(A: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """A x for a batch of small matrices (B, n, n) and vectors (B, n)."""
    return (A * x.unsqueeze(1)).sum(2)


def _t_apply(A: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """A^T x for a batch of small matrices (B, n, n) and vectors (B, n)."""
    return (A * x.unsqueeze(2)).sum(1)


def _inverse_softplus(y: float) -> float:
    return y + math.log(-math.expm1(-y))


class LearnedGazFriction(nn.Module):
    """Gaz et al. 2019 sigmoid friction with learnable per-joint parameters.

    tau_f(qd) = phi1 (sigmoid(phi2 (qd + phi3)) - sigmoid(phi2 phi3)) [Nm]:
    zero at rest, saturating near +-phi1. phi1 [Nm] and phi2 [s/rad] stay
    positive through softplus; phi3 [rad/s] (the asymmetry) is free.
    """

    def __init__(self, nv: int, phi1: float = 0.3, phi2: float = 10.0):
        super().__init__()
        self.raw_phi1 = nn.Parameter(torch.full((nv,), _inverse_softplus(phi1)))
        self.raw_phi2 = nn.Parameter(torch.full((nv,), _inverse_softplus(phi2)))
        self.phi3 = nn.Parameter(torch.zeros(nv))

    @property
    def phi1(self) -> torch.Tensor:
        return nn.functional.softplus(self.raw_phi1)

    @property
    def phi2(self) -> torch.Tensor:
        return nn.functional.softplus(self.raw_phi2)

    def forward(self, qd: torch.Tensor) -> torch.Tensor:
        p1, p2, p3 = self.phi1, self.phi2, self.phi3
        return p1 * (torch.sigmoid(p2 * (qd + p3)) - torch.sigmoid(p2 * p3))


# ------------------------------------------------------------ the kind
def _build_delan(p, n_in, n_out, widths):
    """DeLaN, its learned friction, and a residual branch of a net kind (ReLU)."""
    nv = widths["q"]
    if list(p.inputs[:3]) != ["q", "qd", "qdd"] or n_out != nv:
        raise ValueError(f"preset {p.name!r}: DeLaN needs inputs q, qd, qdd first and joint-torque targets")
    delan = DeepLagrangianNetwork(nv, p.delan_hidden, p.delan_eps)
    friction = LearnedGazFriction(nv) if p.friction else None
    net = None
    if p.residual_kind:
        net = build_net(p.residual_kind, n_in, n_out, p.window, p.front_units, p.fc_layers, p.fc_units, "relu",
                        p.conv_kernel)
    return {"delan": delan, "friction": friction, "net": net}


def _search_delan(trial, base) -> dict:
    depth = trial.suggest_categorical("delan_layers", SPACE["delan_layers"])
    width = trial.suggest_categorical("delan_units", SPACE["delan_units"])
    return {"delan_hidden": (width,) * depth}


# Budgeted steps and cost rank: see the note above the net kinds (``nets.py``); a DeLaN with a
# residual net counts as DeLaN.
NETWORK_KINDS.register(NetworkKind("delan", "Deep Lagrangian Network: H = L L^T + eps I, V(q); c, g by autograd",
                     build=_build_delan, fast=fast_path("delan_fast"), clips_gradients=False, cost_rank=2,
                     search=_search_delan, budget_steps=16000, sequence=False, needs_front=False, parts=DELAN_PARTS))
