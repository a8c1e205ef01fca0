"""The sensors' noise specification: what the generator draws, and what the estimator's rule assumes
when it has no noise window of its own.

It sits beside the robot's description so that both the simulator (``sim/``, which draws the noise)
and the analytic layer (``analytic/methods.spec_noise``, which reads the levels) can read it: one
specification, below both. ``sim.generator_config.NoiseConfig`` is this class.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass


@dataclass(frozen=True)
class NoiseConfig:
    """Sensor noise: white, zero-mean Gaussian standard deviations, plus a
    per-instance base-sensor bias drawn uniformly in [-bias, bias] per axis.

    Noise on q and qd is drawn at the simulation rate (the controller sees it
    too); the others at the recording rate. Levels are those of a Panda's
    encoders and joint torque sensors and of a mid-range 6-axis F/T sensor.
    The controller's gains turn q/qd noise into command jitter (Kp sigma_q +
    Kd sigma_qd, ~0.17 rad/s^2 here, ~0.2 Nm on joints 1-4): ten times these
    levels would bury the joint-torque task in it.
    """

    q: float = 2e-5             # rad
    qd: float = 5e-4            # rad/s
    tau_J: float = 0.05         # Nm, link-side joint torque sensors
    force: float = 0.2          # N, base sensor forces
    torque: float = 0.01        # Nm, base sensor moments
    force_bias: float = 2.0     # N, per-instance offset bound
    torque_bias: float = 0.1    # Nm, per-instance offset bound

    @classmethod
    def off(cls) -> "NoiseConfig":
        return cls(**{f.name: 0.0 for f in dataclasses.fields(cls)})


@dataclass(frozen=True)
class SensorDrift:
    """Each sensor's stated bias drift after its zero (tare): what the estimator's error bar and its drift
    follower assume. base_force [N/s], base_torque [Nm/s]: the base F/T sensor (the toolkit's hardware
    sensor model, ``benchmarks/tip_force_stream.py``'s ``hardware`` stream, drifts 0.3 N over 12 s);
    tau_J [Nm/s]: the link-side joint torque sensors (zeroed by the arm's firmware: none stated)."""

    base_force: float = 0.025
    base_torque: float = 0.0
    tau_J: float = 0.0


SENSOR_DRIFT = SensorDrift()
