"""Taring the base force/torque sensor: remove its offset before the base-wrench method.

The detail (what it computes, the equations, why each choice): docs/design/analytic.md, section ``analytic/tare.py``.
"""
from __future__ import annotations

import math

import numpy as np

TARE_SECONDS = 0.5  # s: contact-free start of every generated instance used for the tare


def tare_samples(record_hz: float, tare_seconds: float = TARE_SECONDS) -> int:
    """Number of samples in the tare window (at least 1 when tare_seconds > 0)."""
    if tare_seconds <= 0:
        return 0
    return max(1, int(round(tare_seconds * record_hz)))


def base_sensor_offset(robot, q, qd, qdd, base_wrench) -> np.ndarray:
    """The sensor offset (6,) [N, Nm] from contact-free samples (N, ...): mean(measured - model)."""
    w = np.atleast_2d(np.asarray(base_wrench, float))
    model = np.atleast_2d(robot.base_wrench(np.atleast_2d(q), np.atleast_2d(qd), np.atleast_2d(qdd)))
    return (w - model).mean(axis=0)


def tared_base_wrench(robot, q, qd, qdd, base_wrench, n_tare: int) -> np.ndarray:
    """One run's base wrench (T, 6) with the offset from its first ``n_tare`` samples removed.

    n_tare = 0 returns the wrench unchanged (no tare).
    """
    w = np.asarray(base_wrench, float)
    if n_tare <= 0:
        return w
    n = min(n_tare, len(w))
    return w - base_sensor_offset(robot, q[:n], qd[:n], qdd[:n], w[:n])


class StreamingTare:
    """The same tare in a control loop: a running mean over the first ``n_calls`` samples.

    ``update`` returns the wrench with the current offset removed; during the
    tare window the offset is the mean so far, after it the offset is frozen.
    """

    def __init__(self, robot, n_calls: int):
        self.robot = robot
        self.n_calls = int(n_calls)
        self.residuals = np.zeros((self.n_calls, 3))  # per window call: measured - model force [N]
        self.moments = np.zeros((self.n_calls, 3))  # and moment [Nm]
        # The tool point [m] per window call, in root coordinates: with the residual's moment there, what
        # ``held_force`` reads (a force at the tool moves the moment with the tool).
        self.positions = np.zeros((self.n_calls, 3))
        self.reset()

    def reset(self) -> None:
        self.count = 0
        self.offset = np.zeros(6)
        self.found = None  # the offset the window found (or was given), before any drift was followed

    @property
    def done(self) -> bool:
        return self.count >= self.n_calls

    def update(self, q, qd, qdd, base_wrench) -> np.ndarray:
        """The tared wrench of one sample that its caller has validated (finite, (nv,) and (6,) float
        arrays: the estimator's gate), so the model wrench skips ``Robot.base_wrench``'s checks."""
        if not self.done:  # only during the tare window: after it, one subtraction per call
            residual = base_wrench - self.robot.base_wrench_single(q, qd, qdd)
            self.residuals[self.count] = residual[:3]
            self.moments[self.count] = residual[3:]
            self.positions[self.count] = self.robot.tip_position_single(q)
            self.count += 1
            self.offset += (residual - self.offset) / self.count
            if self.done:
                self.found = self.offset.copy()
        return base_wrench - self.offset

    def follow(self, q, base_wrench, rate: float, max_step: np.ndarray) -> np.ndarray:
        """At a standstill with no contact: move the offset toward this sample's residual (measured minus
        the model's gravity wrench at q) by the fraction ``rate`` (dt / tau), but by no more than
        ``max_step`` (6,) [N, Nm] per axis: the sensor's stated drift in one call. A slow re-tare that tracks
        the bias drift and cannot absorb a contact that builds faster than the sensor drifts. The caller
        decides that the arm stands still and that nothing is seen touching it. Returns the lag (6,) [N, Nm]:
        this residual less the offset before the step."""
        zero = np.zeros_like(q)
        lag = base_wrench - self.robot.base_wrench_single(q, zero, zero) - self.offset
        self.offset += np.clip(rate * lag, -max_step, max_step)
        return lag

    def residual_change(self, threshold: float, segments: int = 5) -> float | None:
        """``residual_change`` on this window's residuals, once it is full (None before)."""
        if not self.done:
            return None
        return residual_change(self.residuals, threshold, segments)

    def moment_change(self, threshold: float, segments: int = 5) -> float | None:
        """``residual_change`` of the window's moment residuals [Nm]: a force held at the tool through the
        window while the tool moved (its moment p x F changes with p, its force does not)."""
        if not self.done:
            return None
        return residual_change(self.moments, threshold, segments)

    def held_force(self, threshold: float) -> float | None:
        """``held_tool_force`` of the full window: a force held at the tool while it moved."""
        if not self.done:
            return None
        root_moments = self.robot.base_wrench_to_root(np.hstack([self.residuals, self.moments]))[:, 3:]
        return held_tool_force(self.positions, root_moments, threshold)

    def set_offset(self, offset) -> None:
        """Use a known offset (e.g. from a tare done elsewhere) and skip the tare window."""
        offset = np.asarray(offset, float)
        if offset.shape != (6,) or not math.isfinite(offset.dot(offset)):
            raise ValueError(f"a base-sensor offset is 6 finite values [N, Nm], got {offset!r}")
        self.offset = offset.copy()
        self.found = offset.copy()
        self.count = self.n_calls


def window_force(forces: np.ndarray, threshold: float) -> float | None:
    """The force [N] a window's joint torques see (the median of its per-sample estimates (n, 3)) when it
    exceeds ``threshold`` [N], else None: a contact held through the whole window, which the base
    sensor alone cannot tell from its offset."""
    f = np.median(np.asarray(forces, float), axis=0)
    seen = math.sqrt(float(f.dot(f)))
    return seen if seen > threshold else None


def robust_sigma(x: np.ndarray) -> np.ndarray:
    """Per column of x (n, k), its white noise's standard deviation from the median absolute deviation
    (1.4826 MAD): medians by partial sort (the upper one of an even count), as a control cycle runs this."""
    half = len(x) // 2
    center = np.partition(x, half, axis=0)[half]
    return 1.4826 * np.partition(np.abs(x - center), half, axis=0)[half]


def residual_change(residuals: np.ndarray, threshold: float, segments: int = 5) -> float | None:
    """The largest change [N] of a window's force residual (measured - model, (n, 3)) between its segments
    when it exceeds ``threshold`` [N], else None: a contact that began or ended inside the window, or a
    trend, which a mean would tare into the offset. Medians (the upper one of an even count) of
    ``segments`` equal parts, so a sensor's white noise and a few outliers do not trip it; on a noisy
    residual the bar rises to six times the noise of a difference of two such medians."""
    r = np.asarray(residuals, float)
    if len(r) < 2 * segments:
        return None
    # A window's last call runs this inside a control cycle: one partial sort per segment, no Python loop
    # over its samples.
    parts = np.array_split(r, segments)
    medians = np.stack([np.partition(p, len(p) // 2, axis=0)[len(p) // 2] for p in parts])
    gaps = medians[:, None, :] - medians[None, :, :]
    spread = float(np.sqrt((gaps * gaps).sum(axis=2).max()))
    # The residual's own noise (MAD, per axis) moves a segment's median by ~1.25 sigma / sqrt(n): a
    # change within six such (of a difference of two medians) is no evidence of a contact.
    sigma = robust_sigma(r)
    noise_limit = 6.0 * 1.25 * math.sqrt(2.0) * float(np.linalg.norm(sigma)) / math.sqrt(len(parts[-1]))
    return spread if spread > max(threshold, noise_limit) else None


def held_tool_force(positions: np.ndarray, moments: np.ndarray, threshold: float,
                    significance: float = 5.0, min_motion: float = 0.003) -> float | None:
    """The force [N] held at the tool through a window that its moment residuals reveal, when it exceeds
    ``threshold`` [N], else None.

    positions (n, 3) [m]: the tool point per sample; moments (n, 3) [Nm]: the base sensor's moment residual
    (measured - model) about the root origin, both in root coordinates. A force F held at the tool adds
    -p x F to the moment, an offset adds a constant: so m - mean(m) = F x (p - mean(p)), linear in F, which
    least squares solves along the directions the tool's motion excites (the eigenvectors of
    sum |dp|^2 I - dp dp^T). A component counts where it exceeds ``threshold`` and ``significance`` times
    its standard error (from the moment's noise), along a direction across which the tool moved at least
    ``min_motion`` [m] RMS; a window without motion excites none: a force held at a standstill stays
    undecidable from the offset, as it is."""
    p, m = np.asarray(positions, float), np.asarray(moments, float)
    n = len(p)
    if n < 8:
        return None
    dp, dm = p - p.mean(0), m - m.mean(0)
    normal = float((dp * dp).sum()) * np.eye(3) - dp.T @ dp
    lam, vec = np.linalg.eigh(normal)
    rhs = np.cross(dp, dm).sum(0)
    # A direction counts where the tool moved at least min_motion [m] RMS across it: a sensor's slow drift
    # (not white, so not in the noise below) over a smaller motion would fit an arbitrarily large force.
    excited = lam > n * min_motion ** 2
    if not excited.any():
        return None
    coef = np.where(excited, (vec.T @ rhs) / np.where(excited, lam, 1.0), 0.0)
    # The moment's white noise from its sample-to-sample differences (MAD): a contact's edge inside the
    # window (a step) would inflate the fit's own residual and hide the force it leaves behind.
    sigma = float(np.sqrt(np.mean(robust_sigma(m[1:] - m[:-1]) ** 2) / 2.0))
    se = sigma / np.sqrt(np.where(excited, lam, np.inf))
    seen = excited & (np.abs(coef) > threshold) & (np.abs(coef) > significance * se)
    size = float(np.sqrt((coef[seen] ** 2).sum()))
    return size if seen.any() else None


class TaredRun:
    """A run (a dataset Instance, or anything indexable by field name with ``len``) whose
    ``base_wrench`` reads tared on its first ``n_tare`` samples; every other field, and
    every attribute (``name``, ``truth``, ...), is the run's own.

    The tare is computed on first use, from the run's q, qd, qdd and base wrench.
    """

    def __init__(self, run, robot, n_tare: int):
        self._run, self._robot, self._n_tare = run, robot, int(n_tare)
        self._tared = None

    @property
    def base_wrench(self) -> np.ndarray:
        if self._tared is None:
            r = self._run
            self._tared = tared_base_wrench(self._robot, r["q"], r["qd"], r["qdd"], r["base_wrench"], self._n_tare)
        return self._tared

    def __getitem__(self, key: str):
        return self.base_wrench if key == "base_wrench" else self._run[key]

    def __getattr__(self, key: str):  # only for what this class does not define
        if key.startswith("_"):
            raise AttributeError(key)
        return getattr(self._run, key)

    def __len__(self) -> int:
        return len(self._run)


def tared_runs(runs, robot, record_hz: float, tare_seconds: float = TARE_SECONDS) -> list:
    """The runs with their base sensor tared on each one's first ``tare_seconds`` [s] (0: unchanged).

    The one definition of the tare that every row's inputs go through: the analytic rows,
    the residual nets' physics part and the learned rows' own inputs.
    """
    runs = list(runs)
    n = tare_samples(record_hz, tare_seconds)
    return runs if n == 0 else [TaredRun(r, robot, n) for r in runs]
