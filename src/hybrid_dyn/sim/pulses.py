"""External force at the tool point: the seed's Gaussian bell pulses (PROTOCOL 3).

Seed section 3.1 models the experimenter's push as a sum of bells,

    F(t) = sum_i  s_i A_i exp(-(t - tau_i)^2 / (2 sigma_i^2)) u_i,

with n uniform in [5, 15] per instance, A_i uniform in [5, 20] N, an unbiased
random sign s_i, the gap between bell centres uniform in [5, 10] s and sigma_i
uniform in [0.5, 1.5] s. The seed does not say in which direction a bell
pushes; PROTOCOL 3 fixes a uniformly random unit direction u_i per bell.

The first centre lies one gap after t = 0. Bells whose centre falls beyond the
end of an instance are simply not seen (the seed's instances, ~200 s, hold
nearly all of them; short test instances hold fewer).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scenarios import PulseConfig


@dataclass(frozen=True)
class BellPulses:
    """A drawn pulse train: per bell the centre [s], width [s], signed amplitude [N], direction."""

    centre: np.ndarray     # (n,)
    sigma: np.ndarray      # (n,)
    amplitude: np.ndarray  # (n,), signed
    direction: np.ndarray  # (n, 3), unit vectors in the base frame

    def __len__(self) -> int:
        return len(self.centre)

    def force(self, t: np.ndarray) -> np.ndarray:
        """Force [N] (T, 3) on the robot at the tool point at times ``t`` [s] (T,)."""
        t = np.asarray(t, float)
        out = np.zeros((len(t), 3))
        for c, s, a, u in zip(self.centre, self.sigma, self.amplitude, self.direction):
            # Beyond 8 sigma a bell is below 1e-13 of its peak: skip the exp there.
            near = np.abs(t - c) < 8.0 * s
            out[near] += (a * np.exp(-0.5 * ((t[near] - c) / s) ** 2))[:, None] * u
        return out

    def to_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in ("centre", "sigma", "amplitude", "direction")}


def sample_pulses(rng: np.random.Generator, cfg: PulseConfig = PulseConfig()) -> BellPulses:
    """Draw one instance's pulse train (PROTOCOL 3)."""
    n = int(rng.integers(cfg.count[0], cfg.count[1] + 1))
    gaps = rng.uniform(cfg.gap[0], cfg.gap[1], n)
    sigma = rng.uniform(cfg.sigma[0], cfg.sigma[1], n)
    sign = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    amplitude = sign * rng.uniform(cfg.amplitude[0], cfg.amplitude[1], n)
    direction = rng.normal(size=(n, 3))  # isotropic Gaussian -> uniform on the sphere
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return BellPulses(np.cumsum(gaps), sigma, amplitude, direction)
