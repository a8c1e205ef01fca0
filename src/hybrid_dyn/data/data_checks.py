"""Checks of data before it is used: split fractions, logged channels that carry nothing, angles in the
wrong unit, and data whose motion cannot identify or test a model.

Each check returns a list of one-line problems (empty: the input is fine), so that its caller raises its
own ``HybridDynError`` subclass with its own context (a spec file, a dataset) and no check hides
another. Nothing here reads a file or writes one.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

# ------------------------------------------------------------------- split fractions
def split_problems(seed, test_frac, val_frac) -> list[str]:
    """Why a split (``split_by_instance``: ``test_frac`` of the instances to test, then ``val_frac`` of the
    rest to validation, seeded by ``seed``) cannot leave three non-empty splits: a seed that is not a
    non-negative integer, fractions that are not numbers strictly between 0 and 1."""
    out = []
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        out.append(f"split seed must be a non-negative integer, got {seed!r}")
    for key, value in (("test_frac", test_frac), ("val_frac", val_frac)):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            out.append(f"{key} must be a number, got {value!r}")
        elif not 0 < value < 1:
            out.append(f"{key} must lie strictly between 0 and 1 (a fraction of the instances), got {value!r}")
    return out


def empty_split_problems(splits: dict) -> list[str]:
    """The splits of ``{"train": [...], "val": [...], "test": [...]}`` that hold nothing."""
    empty = [s for s in ("train", "val", "test") if not splits.get(s)]
    return [f"the {', '.join(empty)} split{'s are' if len(empty) > 1 else ' is'} empty"] if empty else []


# ------------------------------------------------------------------ angle units
def angle_unit_problems(angle_unit: str, q_peak_rad: float) -> list[str]:
    """Why a log declared in degrees looks like radians: ``q_peak_rad``, its largest |q| after conversion,
    is below pi degrees, so every joint stayed within +-3.14 logged units, which is every radian log of an
    arm whose limits lie within +-pi (the Panda's) and no log of an arm moving in degrees. Read as degrees
    the Panda's joint 4 (-2.36 rad) becomes -0.04 rad, outside its [-3.07, -0.07]; a bound with the
    import's margin does not see that, this does."""
    if angle_unit == "deg" and q_peak_rad <= math.pi * math.pi / 180:
        return [f"angle = \"deg\", but every logged joint position lies within +-pi ({q_peak_rad * 180 / math.pi:.3g} "
                "at most): the log is in radians; remove [units] angle or set it to \"rad\""]
    return []


# ------------------------------------------------------------ logged channels
def _joint_label(j: int, joint_names) -> str:
    """'joint 4 (panda_joint4)': 1-based, with the robot's name for it when known."""
    return f"joint {j + 1}" + (f" ({joint_names[j]})" if joint_names is not None and j < len(joint_names) else "")


def channel_problems(signal: str, values, unit: str, expected_scale=None, scale_factor: float = 1e-3,
                     joint_names=None) -> list[str]:
    """Per-joint channels of one logged signal (``values`` (N, nv) in ``unit``) that carry no information:

    - *constant*: the same value in every row (a dead sensor or a cable that is not connected reads 0
      throughout; a joint that never moves reads one angle);
    - *far below its joint's scale* (only with ``expected_scale`` (nv,), e.g. the joints' effort limits
      [Nm]): the channel's standard deviation over its joint's scale is less than ``scale_factor`` times
      the median of that ratio over the joints (a live channel sits within a decade or two of the others;
      a dead one that carries only ADC noise, 1e-4 Nm on an 87 Nm joint, is five decades below).
    """
    x = np.asarray(values, float)
    if x.ndim != 2 or len(x) < 2:
        return []
    return channel_problems_of(signal, len(x), x[0], x.std(axis=0), np.ptp(x, axis=0) == 0, unit, expected_scale,
                               scale_factor, joint_names)


def channel_problems_of(signal: str, n: int, first, spread, constant, unit: str, expected_scale=None,
                        scale_factor: float = 1e-3, joint_names=None) -> list[str]:
    """:func:`channel_problems` from the channels' statistics over ``n`` rows (a log read in blocks): the first
    row ``first`` (nv,), the standard deviations ``spread`` (nv,) and which channels are ``constant``."""
    if n < 2:
        return []
    out = []
    for j in np.flatnonzero(constant):
        out.append(f"{signal} of {_joint_label(j, joint_names)} is constant ({first[j]:.6g} {unit}) in all {n} "
                   f"rows: a dead channel{' or a joint that never moves' if signal == 'q' else ''}?")
    if expected_scale is not None:
        ratio = spread / np.asarray(expected_scale, float)
        ref = float(np.median(ratio))
        for j in np.flatnonzero((ratio < scale_factor * ref) & ~constant):
            out.append(f"{signal} of {_joint_label(j, joint_names)} varies by {spread[j]:.3g} {unit} (std), "
                       f"{ratio[j] / ref:.2g} x the joints' median relative to their scale "
                       f"(threshold {scale_factor:g}): a dead channel?")
    return out


# ------------------------------------------------------------ motion of a data split
@dataclass(frozen=True)
class MotionThresholds:
    """What a split's motion must reach to identify or test what a model claims.

    min_range_rad [rad]: a joint whose range of motion (max - min of q) in the data a model is fitted on is
      below this (5 degrees) leaves the joint's parameters unidentified: its gravity torque is seen at one
      angle and its inertia, Coriolis and friction terms hardly at all;
    standstill_qd_rms [rad/s]: below this RMS velocity (over the samples and joints of a test split) the
      friction and velocity terms are not tested (0.05 rad/s = 2.9 deg/s; the Panda's Coulomb friction
      switches within about 0.02 rad/s);
    standstill_qdd_rms [rad/s^2]: below this RMS acceleration the inertia terms are not tested (0.1 rad/s^2
      moves the Panda's inertial torques by a few hundredths of a Nm, within its torque sensors' noise).
    """

    min_range_rad: float = math.radians(5.0)
    standstill_qd_rms: float = 0.05
    standstill_qdd_rms: float = 0.1


MOTION_THRESHOLDS = MotionThresholds()


def range_of_motion_problems(q, joint_names=None, what: str = "the training data",
                             thresholds: MotionThresholds = MOTION_THRESHOLDS) -> list[str]:
    """The joints whose range of motion (max - min of ``q`` (N, nv) [rad]) is below ``min_range_rad``."""
    q = np.asarray(q, float)
    if q.ndim != 2 or not len(q):
        return []
    rom = np.ptp(q, axis=0)
    lim = thresholds.min_range_rad
    return [f"{_joint_label(j, joint_names)} moves {math.degrees(rom[j]):.2g} deg in {what}, under the "
            f"{math.degrees(lim):.3g} deg needed to identify it: its parameters are not determined by the data"
            for j in np.flatnonzero(rom < lim)]


def standstill_problems(qd, qdd, what: str = "the test split",
                        thresholds: MotionThresholds = MOTION_THRESHOLDS) -> list[str]:
    """Why ``qd``, ``qdd`` (N, nv) [rad/s, rad/s^2] cannot test a dynamics model: an RMS velocity below
    ``standstill_qd_rms`` (friction untested), an RMS acceleration below ``standstill_qdd_rms`` (inertia
    untested). One line; empty when both are reached."""
    qd, qdd = np.asarray(qd, float), np.asarray(qdd, float)
    if not qd.size or not qdd.size:
        return []
    v, a = float(np.sqrt(np.mean(qd**2))), float(np.sqrt(np.mean(qdd**2)))
    slow, still = v < thresholds.standstill_qd_rms, a < thresholds.standstill_qdd_rms
    if not (slow or still):
        return []
    terms = (["friction", "velocity"] if slow else []) + (["inertia"] if still else [])
    untested = (", ".join(terms[:-1]) + " and " if len(terms) > 1 else "") + terms[-1] + " terms"
    head = "is at a standstill" if slow and still else "barely moves"
    return [f"{what} {head} (RMS qd {v:.3g} rad/s, threshold {thresholds.standstill_qd_rms:g}; RMS qdd {a:.3g} "
            f"rad/s^2, threshold {thresholds.standstill_qdd_rms:g}): its {untested} are not tested"]
