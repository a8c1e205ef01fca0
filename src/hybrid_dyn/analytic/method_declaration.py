"""What a tip-force method is: its declaration (:class:`Method`) and one stream of it (:class:`MethodStream`).

The one registry of the methods, :data:`TIP_FORCE_METHODS`, is declared here too, empty: each method's
module registers its own (``TIP_FORCE_METHODS.register(Method(...))`` at its end, its older spellings
beside it), and the catalogue ``methods.py`` imports the built-in ones. A new method's module imports from
here, never from the catalogue (which would make an import circle once the catalogue imports it); a
consumer imports ``TIP_FORCE_METHODS`` from the catalogue, so that the built-in methods are declared.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..description.sensor_noise import NoiseConfig
from ..errors import UsageError
from ..registry import Registry
from .bandwidth import BANDWIDTHS, BandwidthParameter, WindowNoise
from .robot import Robot
from .torque_models import TORQUE_MODELS


class MethodStream:
    """One stream of a method on a robot at rate_hz [Hz]: its bandwidth ``value``, its state.

    Subclasses define ``choose`` (the rule), ``step``, ``batch`` and ``settle_calls``; those with
    state define ``reset``. ``configure`` sets the bandwidth without designing anything."""

    def __init__(self, robot: Robot, rate_hz: float):
        self.robot, self.rate_hz, self.dt = robot, float(rate_hz), 1.0 / float(rate_hz)
        self.value = None
        self.data = robot.model.createData()  # for the rule's Jacobians at the window's pose (made now)

    def choose(self, noise: WindowNoise) -> float:
        """The bandwidth rule on the window's measured noise."""
        raise NotImplementedError

    def configure(self, value: float) -> None:
        self.value = float(value)
        self.reset()

    def reset(self) -> None:
        """Forget the history (a start, a gap)."""

    def model_changed(self) -> None:
        """The robot's model changed in place (``Robot.set_payload``): refresh what was computed from it when
        the stream was made (a weight); the history goes on."""

    def window_step(self, q, qd, qdd, w_raw, tau) -> None:
        """One sample of the noise window (the raw base wrench): only methods that measure more than the
        window's arrays do anything here."""

    def close_window(self, noise: WindowNoise, tare_offset, fixed=None) -> float:
        """The window is over: configure the bandwidth (``fixed``, or the rule's) and return it."""
        self.configure(self.choose(noise) if fixed is None else fixed)
        return self.value

    def fit_window(self, q, qd, qdd, w_tared, tau, noise: WindowNoise, fixed=None) -> float:
        """``close_window`` from the window's arrays (the batch twin); base wrench already tared."""
        return self.close_window(noise, None, fixed)

    def step(self, q, qd, qdd, w, tau) -> np.ndarray:
        """One validated sample (w tared, or None; tau or None) -> the tip force (3,) [N]."""
        raise NotImplementedError

    def batch(self, q, qd, qdd, w, tau) -> np.ndarray:
        """``step`` over a run (N, ...) from a start: (N, 3) [N]."""
        raise NotImplementedError

    def settle_calls(self, sensors=()) -> int:
        """Calls from a start until its transient is below 1 % (with the sensors present)."""
        raise NotImplementedError



@dataclass(frozen=True)
class Method:
    """One analytic tip-force estimator: its declaration, read by every consumer of ``TIP_FORCE_METHODS``.

    reads: the inputs beyond q, qd ("base_wrench", "tau_J"). any_of: a call may bring any non-empty
    subset of them (else all, every call). needs_qdd: the method reads qdd at every call. tares: it
    reads the base sensor tared on the noise window. parameter: the name of its bandwidth parameter,
    a declaration of ``bandwidth.BANDWIDTHS`` (its unit, default and the values the bench's ``-val``
    row chooses from: :attr:`bandwidth`). make(robot, rate_hz) -> :class:`MethodStream`.
    bench_rows: the bench declares its rows from here (False where ``analytic_rows`` declares them).
    residual_prior: a residual network may sit on it (``learn/priors.py``)."""

    name: str
    summary: str
    reads: tuple
    any_of: bool
    needs_qdd: bool
    tares: bool
    parameter: str
    make: Callable[[Robot, float], MethodStream]
    bench_rows: bool = True
    residual_prior: bool = False

    def __post_init__(self):
        if self.parameter not in BANDWIDTHS:
            raise UsageError(f"estimator method {self.name!r}: its bandwidth parameter {self.parameter!r} is not "
                             f"declared; declare it first (bandwidth.BANDWIDTHS.register(BandwidthParameter(...)))")
        if self.name in TORQUE_MODELS or self.name in TORQUE_MODELS.aliases:  # the estimators' one namespace
            raise UsageError(f"analytic estimator {self.name!r} is declared twice")

    @property
    def bandwidth(self) -> BandwidthParameter:
        """The declaration of its bandwidth parameter."""
        return BANDWIDTHS[self.parameter]

    @property
    def unit(self) -> str:
        """Its bandwidth parameter's unit."""
        return self.bandwidth.unit

    def val_grid(self, rate_hz: float) -> tuple:
        """The values of its bandwidth parameter the bench's ``-val`` row chooses from at rate_hz [Hz]."""
        return self.bandwidth.val_grid(rate_hz)

    @property
    def stateful(self) -> bool:
        """A filter (its value at a sample depends on the run before it), started after the noise window."""
        return not self.needs_qdd

    @property
    def fields(self) -> tuple:
        """The dataset fields a batch run reads (qdd: for the tare, or the method)."""
        return ("q", "qd") + (("qdd",) if self.needs_qdd or self.tares else ()) + self.reads


def spec_noise(robot: Robot) -> WindowNoise:
    """The sensors' specifications as a window's noise (the generator's ``NoiseConfig`` defaults): what
    the rule uses when a stream has no noise window (tare_seconds = 0)."""
    c = NoiseConfig()
    return WindowNoise(np.full(robot.nv, c.qd), c.force, np.full(robot.nv, c.tau_J), np.array(robot.spec.home, float))


# The methods by name (declaration order: the bench's row order). A consumer that derives something per
# method (the bench's rows, the residual priors) reads it and listens to it (``TIP_FORCE_METHODS.listen``).
TIP_FORCE_METHODS = Registry("estimator method", UsageError)
