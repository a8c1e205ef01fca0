"""The streaming estimator's configuration and its statuses.

:class:`EstimatorConfig` holds a stream's rate, each method's bandwidth ("auto": the
rule of ``analytic/bandwidth.py``) and the plausibility bounds of the input gate
(``estimator/input.py``); :class:`EstimatorStatus` says what one call's estimate is
worth. Why each bound is what it is: docs/estimator.md.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Mapping

from ..analytic.bandwidth import BANDWIDTHS
from ..analytic.error_bar import DRIFT_RATE, MOTION_GAIN
from ..analytic.tare import TARE_SECONDS
from ..errors import UsageError


class EstimatorStatus(str, Enum):
    """What one call's estimate is worth (``TipForceEstimator.last_status``); the first that applies wins,
    in the order of docs/estimator.md."""

    OK = "ok"
    WARMING_UP = "warming up"            # window, tare, filter or observer still settling
    INPUT_REJECTED = "input rejected"    # this call's sample was bad; the last good estimate was held
    # Each "out of range" says what is out of it: the estimate, or a learned model's input.
    FORCE_OUT_OF_RANGE = "force out of range"  # the estimate exceeds EstimatorConfig.max_tip_force
    OUT_OF_RANGE = "input out of training range"  # learned model: input outside its training distribution
    WRONG_RATE = "wrong rate"            # an untimed stream spaced unlike 1 / call_hz (RateCheck)
    NO_SENSOR = "no usable sensor"       # this call brings nothing the method can estimate from
    UNCERTAIN = "uncertain"              # the predicted error (last_sigma) exceeds EstimatorConfig.max_sigma
    CONTACT_AT_START = "contact at start-up"  # the noise window saw a contact: a new window is under way
    # The same, where the force the joint torques saw through the window was vertical: a tool load (or the arm's
    # weight) other than the model's, or a vertical press; neither is tared (``estimator/stream_starts.py``).
    LOAD_MISMATCH = "load mismatch"
    # Consistency: the sensors contradict the model (``estimator/consistency.py``); no estimate to trust.
    IMPLAUSIBLE_TARE = "tare offset implausible"  # the base sensor's offset beyond its plausible bias (a flipped sign)
    FROZEN_SENSOR = "frozen sensor"      # a sensor repeats its reading exactly, call after call
    CLIPPED_CHANNEL = "F/T channel clipped"  # a base-sensor channel sits at the largest value it read, unchanged
    OFF_TOOL = "contact off the tool"    # the sensors see a load no force at the tool explains
    # The joint-torque methods' damped solve shrinks a force along the weak direction of J_v: no promise there.
    NEAR_SINGULARITY = "near a singularity"
    # The joint-torque sensors' offsets (``estimator/torque_tare.py``): found beyond max_torque_offset, or drifted
    # since their last standstill beyond what the error bar may carry.
    TORQUE_OFFSET = "torque sensor offset"
    # The model's stated uncertainty (the error bar's model term: inertials, payload; ``estimator/model_term.py``)
    # alone puts sigma beyond max_sigma at this pose and motion: a calibration on the arm's own log narrows it.
    MODEL_UNCERTAIN = "model uncertain"


def _auto_or_positive(name: str, value, unit: str) -> None:
    if value != "auto" and not (isinstance(value, (int, float)) and value > 0):
        raise UsageError(f"{name} must be 'auto' or > 0 [{unit}], got {value!r}")


@dataclass(frozen=True)
class EstimatorConfig:
    """call_hz: the nominal call rate [Hz] the filters and observers are designed for.
    qdd_cutoff_hz [Hz], momentum_gain (observer bandwidth K [1/s]), fusion_force_rate
    (kalman-fusion's random-walk intensity of the tip force [N/sqrt(s)]): each method's
    bandwidth; "auto" (the default): chosen by the rule of ``analytic/bandwidth.py`` from
    the noise window, as the bench's headline rows choose it; a number: used as is.
    bandwidths: the setting of every other bandwidth parameter registered there (a method's
    own, declared with it), by name; :meth:`bandwidth` reads any of them, :meth:`from_settings`
    takes them as keywords. Each is checked by its declaration (``BandwidthParameter.check``).
    on_bad_input: "raise" or "hold".
    tare_seconds: the contact-free start used as the noise window and to tare the base
    sensor [s]; 0 = no window: trust the sensor's zero, the rule on the specifications.
    tare_contact_force: the noise window is trusted only when nothing touched the arm: its base-sensor
    residual (measured - model) changes by less than this between the window's parts, and the joint
    torques (where the method reads them) see a force below it [N]; else a new window starts (status
    "contact at start-up"). A kalman-fusion tare after the window (a base sensor that joins late)
    starts over while the joint torques see a force above it.
    tare_held_force: a force held at the tool through the whole window, which the base force alone
    cannot tell from its offset, is seen in motion by its moment (p x F moves with the tool,
    ``tare.held_tool_force``); a window whose moments reveal one above this [N] is refused too. Higher
    than tare_contact_force: in motion the model's wrench errs with the window's filtered qdd, and that
    error's moment follows the motion as well: at 1 N it refused the contact-free start-up window of a bag
    replayed with the default joint filter (``tests/estimator/test_estimate_from_bag.py``). Only directions across which the tool moved 3 mm RMS in the
    window count: over less motion a slow drift of the moment fits any force, so a press held through a
    window that still stays undecidable, as at a standstill.
    encoder_resolution: the joint encoders' resolution [rad per count]; "auto" takes the robot
    description's (1e-5 rad on the Panda). Above 0, q (quantized) becomes q, qd and qdd through the
    joint-state Kalman filter (``analytic/joint_state.py``) that every method reads; the reported qd is
    not used (a drive's qd is the difference of the same quantized q). 0: exact encoders, q and qd used
    as given (a simulation's, or a dataset whose sensor model says so).
    joint_filter_bandwidth: that filter's bandwidth [rad/s] ("auto": ``joint_state.DEFAULT_OMEGA``).
    stamp_jitter: how far a timed stream's stamps may stray from the robot's sample clock [s]: a stamp
    whose step from the last accepted one lies within max(rate_tolerance / call_hz, 1.5 stamp_jitter) of the
    period (never 0.9 periods or more) is the next tick; a longer step is a gap of
    round(step / period) ticks. The filters run on the nominal period (the robot samples on its own clock; the
    stamps carry the PC's jitter).
    bridge_seconds: a gap up to this long [s] is bridged (its samples interpolated between the two it lies
    between; no new warm-up); a longer one restarts the filters and the method (a warm-up).

    max_sigma: a call is ``ok`` only while its predicted 1-sigma error (``last_sigma``) is below this on
    every axis [N]; above it the status is "uncertain". "auto": a calibration's (``estimator/calibration.py``:
    1.5 times the 99th percentile of sigma on the user's own log), else MAX_SIGMA (0.8 N). motion_sigma_gain [N per rad/s^2] and
    base_drift_rate [N/s, the base sensor's bias drift after its tare]: the error model's motion and
    drift terms (``analytic/error_bar.py``).

    standstill_speed [rad/s], standstill_seconds [s], retare_seconds [s]: after the window, while every
    joint is slower than standstill_speed for standstill_seconds and the estimate is below
    tare_contact_force, the base sensor's tare follows its drift with time constant retare_seconds
    (math.inf: it does not), never faster than twice base_drift_rate (so that it catches up with a drift at that
    rate): a contact that builds faster is not tared away. The follower's lag, averaged over retare_seconds of a
    standstill, verifies the tare once within four times (``call_status.LAG_FACTOR``) base_drift_rate x
    retare_seconds (the drift term starts again from there).

    max_tare_offset [N]: the largest base-sensor offset (force norm) a tare may find; beyond it the sensor
    is not what the model says (a flipped sign, a wrong frame): status "tare offset implausible".
    max_torque_offset [Nm], torque_drift_rate [Nm/s]: the joint-torque sensors' offsets (``estimator/torque_tare.py``):
    the largest per-joint offset the window may find (beyond it: status "torque sensor offset"), and their stated
    drift per joint after the tare (the robot descriptions state none: 0.005 Nm/s, a strain-gauge torque sensor's
    order), carried by the error bar through pinv(J_v^T) and followed at a standstill as the base sensor's.
    frozen_calls: a sensor whose reading repeats exactly this many calls in a row is "frozen sensor"; a base-sensor
    channel that does so at the largest magnitude it has read in the stream is "F/T channel clipped".
    off_tool_moment [Nm], off_tool_torque [Nm]: the part of the base moment (base-sensor methods) or of
    the joint torques (joint-torque methods) that no force at the tool explains, above which (held for
    off_tool_seconds [s]) the status is "contact off the tool" (``estimator/consistency.py``).

    Plausibility bounds (see the module docstring):
    q_margin: how far q may lie outside the URDF position limits [rad]; encoders
    read a hair past a limit, 0.1 rad (6 deg) is no measurement of this arm.
    qd_margin, tau_margin: the fraction by which |qd| may exceed the velocity
    limit (TOML ``max_velocity``, else the URDF's) and |tau_J| the URDF effort
    limit; the arm's controller stops at the limits, so 50 % more is a fault.
    max_tip_force: bound on the estimate [N]. 500 N is beyond what the Panda's
    87 Nm shoulder can hold 0.2 m from its axis; a larger estimate is a fault
    (a corrupt sensor, a singular pose), not a contact. It also sets the
    base-wrench bound. Raise it for a stronger arm.
    rate_tolerance: the fraction by which a timed stream's step may differ
    from 1 / call_hz (and an untimed stream's measured rate, ``RateCheck``).
    inertial_uncertainty, payload_uncertainty_kg: the error bar's model term where no calibration is given
    (``estimator/model_term.py``): the relative 1-sigma of every link's inertials ("auto": the description's
    ``inertial_uncertainty``, 10 % where it states none), and the 1-sigma of a declared payload's mass [kg] (0.05 kg: a tool weighed; set
    your scale's, or more for a guess: a load far from the declared one also shows in the start-up window).
    rated_payload_kg: the largest payload [kg] the arm may be declared to carry (``payload=``,
    ``set_payload``); "auto": the robot description's ``rated_payload_kg`` (none stated: no bound beyond
    50 kg); a number overrides it (a custom arm, a stronger variant), math.inf for none.
    """

    call_hz: float = 1000.0
    qdd_cutoff_hz: float | str = "auto"
    on_bad_input: str = "raise"
    momentum_gain: float | str = "auto"
    tare_seconds: float = TARE_SECONDS
    q_margin: float = 0.1
    qd_margin: float = 0.5
    tau_margin: float = 0.5
    max_tip_force: float = 500.0
    rate_tolerance: float = 0.25
    fusion_force_rate: float | str = "auto"
    tare_contact_force: float = 1.0
    tare_held_force: float = 3.0
    encoder_resolution: float | str = "auto"
    joint_filter_bandwidth: float | str = "auto"
    stamp_jitter: float = 5e-4
    bridge_seconds: float = 0.02
    max_sigma: float | str = "auto"
    motion_sigma_gain: float = MOTION_GAIN
    base_drift_rate: float = DRIFT_RATE
    standstill_speed: float = 5e-3
    standstill_seconds: float = 0.2
    retare_seconds: float = 2.0
    max_tare_offset: float = 20.0
    max_torque_offset: float = 3.0
    torque_drift_rate: float = 0.005
    frozen_calls: int = 20
    off_tool_moment: float = 1.0
    off_tool_torque: float = 1.0
    off_tool_seconds: float = 0.05
    rated_payload_kg: float | str = "auto"
    inertial_uncertainty: float | str = "auto"
    payload_uncertainty_kg: float = 0.05
    # The registered bandwidth parameters without a field of their own (a method registered later): name -> value.
    bandwidths: Mapping[str, float | str] = field(default_factory=dict, hash=False)

    @classmethod
    def from_settings(cls, **settings) -> "EstimatorConfig":
        """The config of keyword settings (``TipForceEstimator.analytic(**settings)``): each field by its name,
        and each registered bandwidth parameter by its name, those without a field going into ``bandwidths``."""
        extra = {k: settings.pop(k) for k in list(settings) if k not in _FIELDS and k in BANDWIDTHS}
        if extra:
            settings["bandwidths"] = {**settings.get("bandwidths", {}), **extra}
        return cls(**settings)

    def bandwidth(self, name: str) -> float | str:
        """The setting of bandwidth parameter ``name`` (``analytic/bandwidth.py``): a number, or "auto" (the rule)."""
        if name in _FIELDS:
            return getattr(self, name)
        return self.bandwidths.get(name, BANDWIDTHS.lookup(name).default)

    def __post_init__(self):
        if self.on_bad_input not in ("raise", "hold"):
            raise UsageError(f"on_bad_input must be 'raise' or 'hold', got {self.on_bad_input!r}")
        if not (isinstance(self.call_hz, (int, float)) and self.call_hz > 0):
            raise UsageError(f"call_hz must be > 0 [Hz], got {self.call_hz!r}")
        object.__setattr__(self, "bandwidths", dict(self.bandwidths))  # the caller's dict may change later
        for name in self.bandwidths:
            if name in _FIELDS:
                raise UsageError(f"bandwidths: {name!r} is a field of its own: set {name}= instead")
            BANDWIDTHS.lookup(name)  # an unknown parameter is refused, naming the registered ones
        for parameter in BANDWIDTHS.values():  # each registered parameter's setting, by its declaration
            parameter.check(self.bandwidth(parameter.name), self.call_hz)
        for name in ("q_margin", "qd_margin", "tau_margin", "tare_seconds"):
            if not getattr(self, name) >= 0:
                raise UsageError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if not self.max_tip_force > 0:
            raise UsageError(f"max_tip_force must be > 0 [N], got {self.max_tip_force!r}")
        _auto_or_positive("max_sigma", self.max_sigma, "N")
        for name in ("standstill_speed", "standstill_seconds", "retare_seconds"):
            if not (isinstance(getattr(self, name), (int, float)) and getattr(self, name) > 0):
                raise UsageError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("max_tare_offset", "max_torque_offset", "frozen_calls", "off_tool_moment", "off_tool_torque",
                     "off_tool_seconds"):
            if not (isinstance(getattr(self, name), (int, float)) and getattr(self, name) > 0):
                raise UsageError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("motion_sigma_gain", "base_drift_rate", "torque_drift_rate"):
            if not (isinstance(getattr(self, name), (int, float)) and getattr(self, name) >= 0):
                raise UsageError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("tare_contact_force", "tare_held_force"):
            if not getattr(self, name) > 0:
                raise UsageError(f"{name} must be > 0 [N], got {getattr(self, name)!r}")
        if self.encoder_resolution != "auto" and not (isinstance(self.encoder_resolution, (int, float))
                                                      and 0 <= self.encoder_resolution < 0.01):
            raise UsageError(f"encoder_resolution must be 'auto' or lie in [0, 0.01) [rad], got {self.encoder_resolution!r}")
        _auto_or_positive("joint_filter_bandwidth", self.joint_filter_bandwidth, "rad/s")
        if not (isinstance(self.bridge_seconds, (int, float)) and 0 <= self.bridge_seconds <= 1.0):
            raise UsageError(f"bridge_seconds must lie in [0, 1] [s], got {self.bridge_seconds!r}")
        if not (isinstance(self.stamp_jitter, (int, float)) and 0 <= self.stamp_jitter < 1.0):
            raise UsageError(f"stamp_jitter must lie in [0, 1) [s], got {self.stamp_jitter!r}")
        _auto_or_positive("rated_payload_kg", self.rated_payload_kg, "kg")
        if self.inertial_uncertainty != "auto" and not (
                isinstance(self.inertial_uncertainty, (int, float)) and 0 <= self.inertial_uncertainty <= 1):
            raise UsageError(f"inertial_uncertainty must be 'auto' or lie in [0, 1] (a relative 1-sigma), got "
                             f"{self.inertial_uncertainty!r}")
        if not (isinstance(self.payload_uncertainty_kg, (int, float)) and 0 <= self.payload_uncertainty_kg
                <= MAX_PAYLOAD_KG):
            raise UsageError(f"payload_uncertainty_kg must lie in [0, {MAX_PAYLOAD_KG:g}] [kg], got "
                             f"{self.payload_uncertainty_kg!r}")
        if not 0 < self.rate_tolerance < 1:
            raise UsageError(f"rate_tolerance must lie in (0, 1), got {self.rate_tolerance!r}")


_FIELDS = frozenset(EstimatorConfig.__dataclass_fields__) - {"bandwidths"}
MAX_SIGMA = 0.8  # [N]: max_sigma's value with no calibration
MAX_PAYLOAD_KG = 50.0  # no arm this toolkit models lifts more; a larger figure is a unit slip (g for kg)


def rated_payload(spec, config: EstimatorConfig) -> float | None:
    """The largest payload [kg] the arm may carry: the config's ``rated_payload_kg``, or ("auto") the robot
    description's (None: it states none)."""
    rated = config.rated_payload_kg
    return spec.rated_payload_kg if rated == "auto" else float(rated)


def checked_payload(payload, rated: float | None = None, robot: str = "the arm") -> tuple:
    """``(mass_kg, (x, y, z))`` as floats, or UsageError naming what is wrong with it; a mass above ``rated``
    [kg] (``rated_payload``) is refused."""
    try:
        mass, com = payload
        mass, com = float(mass), tuple(float(x) for x in com)
    except (TypeError, ValueError):
        raise UsageError(f"payload must be (mass_kg, (x, y, z) m in the tool frame), got {payload!r}") from None
    if len(com) != 3 or not all(math.isfinite(x) for x in com) or max(abs(x) for x in com) > 1.0:
        raise UsageError(f"payload centre of mass must be 3 finite numbers within 1 m of the tool frame [m], got {com!r}")
    if not 0.0 <= mass <= MAX_PAYLOAD_KG:
        raise UsageError(f"payload mass must lie in [0, {MAX_PAYLOAD_KG:g}] kg, got {mass!r}")
    check_rating(mass, rated, robot)
    return mass, com


def check_rating(mass: float, rated: float | None, robot: str = "the arm") -> None:
    """UsageError when a payload of ``mass`` [kg] exceeds the arm's ``rated`` payload [kg] (None: no bound)."""
    if rated is not None and mass > rated:
        raise UsageError(f"payload {mass:g} kg exceeds the rated payload of {robot} ({rated:g} kg, its description's "
                         "rated_payload_kg; rated_payload_kg= in the estimator's config overrides it)")
