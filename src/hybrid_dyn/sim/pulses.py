"""External force at the tool point: the seed's Gaussian bell pulses (PROTOCOL 3),
and the step and trapezoid contacts of the ``contact-steps`` scenario.

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

from .generator_config import ContactStepConfig, PulseConfig, StartTouchConfig


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


@dataclass(frozen=True)
class ContactSteps:
    """Drawn contacts: per contact the start [s], rise time [s], plateau [s], amplitude [N] and direction.

    The force ramps linearly from 0 to the amplitude in ``rise``, holds for
    ``plateau``, and ramps back to 0 in ``rise``. A step has a rise of one
    control period, so the plant sees it as a jump between two 1 ms ticks.
    """

    start: np.ndarray      # (n,)
    rise: np.ndarray       # (n,)
    plateau: np.ndarray    # (n,)
    amplitude: np.ndarray  # (n,), >= 0
    direction: np.ndarray  # (n, 3), unit vectors in the base frame

    def __len__(self) -> int:
        return len(self.start)

    @property
    def end(self) -> np.ndarray:
        return self.start + 2 * self.rise + self.plateau

    def force(self, t: np.ndarray) -> np.ndarray:
        """Force [N] (T, 3) on the robot at the tool point at times ``t`` [s] (T,)."""
        t = np.asarray(t, float)
        out = np.zeros((len(t), 3))
        for t0, r, p, a, u in zip(self.start, self.rise, self.plateau, self.amplitude, self.direction):
            # Trapezoid = clip(ramp up) - clip(ramp down): 0 before t0, 1 on the plateau, 0 after the end.
            shape = np.clip((t - t0) / r, 0.0, 1.0) - np.clip((t - t0 - r - p) / r, 0.0, 1.0)
            out += (a * shape)[:, None] * u
        return out

    def to_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in ("start", "rise", "plateau", "amplitude", "direction")}


def sample_contact_steps(rng: np.random.Generator, cfg: ContactStepConfig, dt: float) -> ContactSteps:
    """Draw one instance's contacts; ``dt`` [s] is the control period, a step's rise."""
    n = int(rng.integers(cfg.count[0], cfg.count[1] + 1))
    is_step = rng.random(n) < cfg.step_fraction
    rise = np.where(is_step, dt, rng.uniform(cfg.rise[0], cfg.rise[1], n))
    plateau = rng.uniform(cfg.plateau[0], cfg.plateau[1], n)
    amplitude = rng.uniform(cfg.amplitude[0], cfg.amplitude[1], n)
    gaps = rng.uniform(cfg.gap[0], cfg.gap[1], n)
    direction = rng.normal(size=(n, 3))  # isotropic Gaussian -> uniform on the sphere
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    start = np.empty(n)
    t = cfg.first_after
    for i in range(n):  # each contact starts one gap after the previous one ended
        start[i] = t + gaps[i]
        t = start[i] + 2 * rise[i] + plateau[i]
    return ContactSteps(start, rise, plateau, amplitude, direction)


def sample_start_touch(rng: np.random.Generator, cfg: StartTouchConfig) -> ContactSteps:
    """Whether an instance is touched during its start-up window (with probability ``cfg.share``) and how:
    a :class:`ContactSteps` of one contact, or of none. The draws are made either way (a fixed count per
    instance)."""
    drawn = rng.random() < cfg.share
    start, amplitude = rng.uniform(*cfg.start), rng.uniform(*cfg.amplitude)
    plateau, rise = rng.uniform(*cfg.plateau), rng.uniform(*cfg.rise)
    direction = rng.normal(size=3)  # isotropic Gaussian -> uniform on the sphere
    n = int(drawn)
    return ContactSteps(np.full(n, start), np.full(n, rise), np.full(n, plateau), np.full(n, amplitude),
                        np.tile(direction / np.linalg.norm(direction), (n, 1)))
