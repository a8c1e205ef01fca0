"""Deep Lagrangian Networks (Lutter, Ritter & Peters 2019), written for this toolkit.

The Lagrangian of a rigid-body system is L = T - V with kinetic energy
T = 1/2 qd^T H(q) qd and potential energy V(q). The Euler-Lagrange equations
give the inverse dynamics

    tau = H(q) qdd + c(q, qd) + g(q),
    c   = dH/dt qd - 1/2 d(qd^T H qd)/dq,   dH/dt = sum_k dH/dq_k qd_k,
    g   = dV/dq.

DeLaN learns H and V with two networks of q and gets c and g by automatic
differentiation (``torch.func.jvp`` and ``torch.func.grad`` on batched maps:
samples are independent, so the gradient of a batch sum is per sample), so every prediction obeys the structure: H is symmetric positive
definite by construction (H = L L^T + eps I with L lower-triangular and a
softplus-positive diagonal), and the learned system conserves its own energy
T + V when no torque acts. Activations are smooth (tanh) since c needs second
derivatives of the networks.

Friction, which the Lagrangian cannot hold, is a separate term: the Gaz et al.
(2019) sigmoid law with learnable per-joint parameters kept positive by
softplus (:class:`LearnedGazFriction`).
"""
from __future__ import annotations

import math

import torch
from torch import nn
from torch.func import grad, jvp

from .nets import glorot_init


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
    def _mass(self, q: torch.Tensor) -> torch.Tensor:
        out = self.l_net((q - self.q_mean) / self.q_std)
        diag = nn.functional.softplus(out[:, : self.nv])
        L = (torch.cat([diag, out[:, self.nv:]], 1) @ self.place).reshape(-1, self.nv, self.nv)
        return L @ L.transpose(1, 2) + self.eps * torch.eye(self.nv, dtype=q.dtype, device=q.device)

    def _potential(self, q: torch.Tensor) -> torch.Tensor:
        return self.torque_scale * self.v_net((q - self.q_mean) / self.q_std)[:, 0]

    def terms(self, q, qd, qdd) -> dict:
        """tau [Nm] (B, nv), H [kg m^2] (B, nv, nv), c and g [Nm] (B, nv), all from the Lagrangian."""
        H, H_dot = jvp(self._mass, (q,), (qd,))  # H_dot = sum_k dH/dq_k qd_k
        dT_dq = grad(lambda q_: 0.5 * torch.einsum("bi,bij,bj->", qd, self._mass(q_), qd))(q)
        c = torch.einsum("bij,bj->bi", H_dot, qd) - dT_dq
        g = grad(lambda q_: self._potential(q_).sum())(q)
        tau = torch.einsum("bij,bj->bi", H, qdd) + c + g
        return {"tau": tau, "H": H, "c": c, "g": g}

    # ---- batched API, q, qd, qdd: (B, nv) [rad, rad/s, rad/s^2]
    def forward(self, q, qd, qdd) -> torch.Tensor:
        """Joint torques [Nm] (B, nv), rigid body part."""
        return self.terms(q, qd, qdd)["tau"]

    def mass_matrix(self, q) -> torch.Tensor:
        """H(q) [kg m^2] (B, nv, nv), symmetric positive definite."""
        return self._mass(q)

    def gravity(self, q) -> torch.Tensor:
        """g(q) = dV/dq [Nm] (B, nv)."""
        return grad(lambda q_: self._potential(q_).sum())(q)

    def energy(self, q, qd) -> torch.Tensor:
        """Learned total energy T + V [J] (B,)."""
        T = 0.5 * torch.einsum("bi,bij,bj->b", qd, self._mass(q), qd)
        return T + self._potential(q)

    def forward_dynamics(self, q, qd, tau) -> torch.Tensor:
        """qdd = H^-1 (tau - c - g) (B, nv): the learned system's free or driven motion."""
        t = self.terms(q, qd, torch.zeros_like(q))
        return torch.linalg.solve(t["H"], (tau - t["c"] - t["g"]).unsqueeze(-1)).squeeze(-1)


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
