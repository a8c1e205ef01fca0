"""The analytic rows of the benchmark: physics on the nominal model, nothing trained.

Each row is declared once, here (``rows.declare``): its name, task, the fields it
reads, and how it predicts a run (batch) and one sample (the call a user makes in a
control loop: the same library functions, an observer or filter stepped once per
call). Adding an analytic row is one ``_analytic(...)`` call in this file.

The observers' gains and the Kalman filter's force rate are chosen on the
validation split, once per scenario (:func:`_chosen_on_val`).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..analytic.base_momentum import BaseMomentumObserver, base_momentum_tip_force
from ..analytic.kalman import KalmanTipForce, tare_window_noise
from ..analytic.momentum_observer import MomentumObserver
from ..analytic.tare import TARE_SECONDS, tare_samples, tared_base_wrench
from ..analytic.tip_force import contact_joint_torques, tip_force_from_base_wrench, tip_force_from_torques
from .rows import Predictor, Row, declare

TARED = "(tared on the first 0.5 s)"  # how the inputs column says a row reads the tared base sensor


def _analytic(name: str, task: str, needs: tuple, inputs, batch_fn, single_fn=None) -> Row:
    """Declare an analytic row: batch_fn(robot, instance, ctx) -> (T, C) and single_fn(robot, instance, k, ctx) -> (C,).

    needs: the dataset fields it reads, its target included; inputs: the results' inputs
    column, a string or ctx -> string (a value chosen on validation)."""
    def build(ds, ctx):
        robot = ctx.robot
        return Predictor(
            predict=lambda insts: [batch_fn(robot, i, ctx) for i in insts],
            single_call=(lambda inst, k: single_fn(robot, inst, k, ctx)) if single_fn else None,
            inputs=inputs(ctx) if callable(inputs) else inputs,
        )

    return declare(Row(name, task, "analytic", needs=needs, needs_urdf=True, build=build))


# The observers' gains and the Kalman filter's force rate set a bandwidth: the best one depends on
# the sample rate and on how fast the contact force changes (bells over seconds, steps in 1 ms).
# Each physics row takes the value of its grid with the least validation RMSE, once per scenario,
# as the learned rows stop on the validation loss: every row is at its best on the same split.
OBSERVER_GAINS = (5.0, 10.0, 20.0, 50.0, 100.0, 200.0)        # K [1/s]; only K dt < 0.5 is tried (stable, no ringing)
FORCE_RATES = (0.1, 0.2, 0.3, 0.6, 1.0, 2.0, 5.0, 10.0)      # Kalman random-walk intensity [N/sqrt(s)]


def _chosen_on_val(ctx, name: str, grid, estimate) -> float:
    """The grid value whose estimate(robot, instance, ctx, value) has the least validation RMSE (cached)."""
    key = ("chosen-on-val", name)
    if key not in ctx.cache:
        val = ctx.dataset.split("val")
        target = np.concatenate([i["tip_force"] for i in val])

        def val_rmse(value):
            return float(np.sqrt(np.mean((np.concatenate([estimate(ctx.robot, i, ctx, value) for i in val])
                                          - target) ** 2)))

        scores = {v: val_rmse(v) for v in grid}
        ctx.cache[key] = min(scores, key=scores.get)
        ctx.log(f"[bench] {ctx.scenario} {name}: validation RMSE by value "
                + ", ".join(f"{v:g}: {e:.4f}" for v, e in scores.items()) + f" -> {ctx.cache[key]:g}")
    return ctx.cache[key]


def _momentum_at(robot, inst, ctx, gain):
    return MomentumObserver(robot, gain=gain, dt=1.0 / ctx.dataset.meta["record_hz"]).run(inst.q, inst.qd, inst.tau_J)[0]


def _gains(ctx) -> tuple:
    """The observer gains worth trying at the data's rate: K dt < 0.5 (at K dt >= 1 the discrete observer rings or diverges)."""
    return tuple(k for k in OBSERVER_GAINS if k / ctx.dataset.meta["record_hz"] < 0.5)


def _momentum_gain(ctx) -> float:
    return _chosen_on_val(ctx, "momentum-observer gain", _gains(ctx), _momentum_at)


def _momentum(robot, inst, ctx):
    return _momentum_at(robot, inst, ctx, _momentum_gain(ctx))


def _observer_single(name: str, make, sensor):
    """A row's single call: an observer (``make(robot, ctx)``) started at the run's first sample and
    stepped once per call on ``sensor(robot, inst, ctx)`` (its (T, k) input), as a control loop runs it."""
    def single(robot, inst, k, ctx):
        if k == 0:
            ctx.cache[name] = make(robot, ctx)
        return ctx.cache[name].step_force(inst.q[k], inst.qd[k], sensor(robot, inst, ctx)[k])

    return single


_momentum_single = _observer_single(
    "momentum-observer", lambda robot, ctx: MomentumObserver(robot, _momentum_gain(ctx), 1.0 / ctx.dataset.meta["record_hz"]),
    lambda robot, inst, ctx: inst.tau_J)


def _tared(robot, inst, ctx) -> np.ndarray:
    """The instance's base wrench tared on its contact-free first TARE_SECONDS (cached per scenario and instance)."""
    key = ("tared-base-wrench", inst.name)
    if key not in ctx.cache:
        n = tare_samples(ctx.dataset.meta["record_hz"], TARE_SECONDS)
        ctx.cache[key] = tared_base_wrench(robot, inst.q, inst.qd, inst.qdd, inst.base_wrench, n)
    return ctx.cache[key]


def _rnea_minus_contact(robot, q, qd, qdd, w):
    """tau = ID(q, qd, qdd) - J_v^T F_bw: RNEA with the base-wrench force estimate as the contact."""
    return robot.inverse_dynamics(q, qd, qdd) - contact_joint_torques(robot, q, tip_force_from_base_wrench(robot, q, qd, qdd, w))


def _base_momentum_at(robot, inst, ctx, gain):
    """The base momentum observer (force rows) on the tared base wrench, started after the tare
    window as a stream starts it."""
    hz = ctx.dataset.meta["record_hz"]
    return base_momentum_tip_force(robot, inst.q, inst.qd, _tared(robot, inst, ctx), 1.0 / hz, gain,
                                   tare_samples(hz, TARE_SECONDS))


def _base_momentum_gain(ctx) -> float:
    return _chosen_on_val(ctx, "base-momentum gain", _gains(ctx), _base_momentum_at)


def _base_momentum(robot, inst, ctx):
    return _base_momentum_at(robot, inst, ctx, _base_momentum_gain(ctx))


_base_momentum_single = _observer_single(
    "base-momentum",
    lambda robot, ctx: BaseMomentumObserver(robot, _base_momentum_gain(ctx), 1.0 / ctx.dataset.meta["record_hz"]),
    _tared)


def _kalman_inputs(robot, inst, ctx):
    """What the fusion filter of one instance needs whatever its force rate, computed once per instance:
    (the sensors' noise with the model errors measured on the contact-free tare window,
    the unexplained momenta of the samples after the window)."""
    key = ("kalman-inputs", inst.name)
    if key not in ctx.cache:
        hz = ctx.dataset.meta["record_hz"]
        n = tare_samples(hz, TARE_SECONDS)
        w = _tared(robot, inst, ctx)
        noise = tare_window_noise(robot, 1.0 / hz, inst.q[:n], inst.qd[:n], w[:n], inst.tau_J[:n])
        y = KalmanTipForce(robot, 1.0 / hz, noise).measurements(inst.q[n:], inst.qd[n:], w[n:], inst.tau_J[n:]) \
            if n < len(inst) else None
        ctx.cache[key] = (noise, y)
    return ctx.cache[key]


def _kalman_filter(robot, inst, ctx, force_rate=None) -> KalmanTipForce:
    """The fusion filter of one instance (``analytic/kalman.py``) at the force rate chosen on validation."""
    noise = _kalman_inputs(robot, inst, ctx)[0]  # the model errors do not depend on the force rate
    rate = _kalman_force_rate(ctx) if force_rate is None else force_rate
    return KalmanTipForce(robot, 1.0 / ctx.dataset.meta["record_hz"], dataclasses.replace(noise, force_rate=rate))


def _kalman_at(robot, inst, ctx, force_rate):
    """The fusion filter started after the tare window, as TipForceEstimator starts it (0 before)."""
    n = tare_samples(ctx.dataset.meta["record_hz"], TARE_SECONDS)
    out = np.zeros((len(inst), 3))
    y = _kalman_inputs(robot, inst, ctx)[1]
    if y is not None:
        out[n:] = _kalman_filter(robot, inst, ctx, force_rate).filter_measurements(y)
    return out


def _kalman_force_rate(ctx) -> float:
    return _chosen_on_val(ctx, "kalman-fusion force rate", FORCE_RATES, _kalman_at)


def _kalman(robot, inst, ctx):
    return _kalman_at(robot, inst, ctx, _kalman_force_rate(ctx))


def _kalman_single(robot, inst, k, ctx):
    """One filter per run, started at its first sample and stepped once per call."""
    if k == 0:
        ctx.cache["kalman-fusion"] = _kalman_filter(robot, inst, ctx)
    return ctx.cache["kalman-fusion"].step(inst.q[k], inst.qd[k], _tared(robot, inst, ctx)[k], inst.tau_J[k])


# ------------------------------------------------------------------ the rows
_analytic("torques-pinv", "tip_force", ("q", "qd", "qdd", "tau_J", "tip_force"), "q, qd, qdd, tau_J",
          lambda r, i, ctx: tip_force_from_torques(r, i.q, i.qd, i.qdd, i.tau_J),
          lambda r, i, k, ctx: tip_force_from_torques(r, i.q[k], i.qd[k], i.qdd[k], i.tau_J[k]))
_analytic("base-wrench", "tip_force", ("q", "qd", "qdd", "base_wrench", "tip_force"), "q, qd, qdd, base_wrench",
          lambda r, i, ctx: tip_force_from_base_wrench(r, i.q, i.qd, i.qdd, i.base_wrench),
          lambda r, i, k, ctx: tip_force_from_base_wrench(r, i.q[k], i.qd[k], i.qdd[k], i.base_wrench[k]))
# The base sensor tared on each instance's contact-free start (analytic/tare.py).
_analytic("base-wrench-tared", "tip_force", ("q", "qd", "qdd", "base_wrench", "tip_force"),
          f"q, qd, qdd, base_wrench {TARED}",
          lambda r, i, ctx: tip_force_from_base_wrench(r, i.q, i.qd, i.qdd, _tared(r, i, ctx)),
          lambda r, i, k, ctx: tip_force_from_base_wrench(r, i.q[k], i.qd[k], i.qdd[k], _tared(r, i, ctx)[k]))
_analytic("momentum-observer", "tip_force", ("q", "qd", "tau_J", "tip_force"),
          lambda ctx: f"q, qd, tau_J; gain {_momentum_gain(ctx):g}/s (chosen on val)", _momentum, _momentum_single)
# Issue 16: Newton's law for the whole robot (no qdd; qdd only for the tare), and both force sensors fused.
_analytic("base-momentum", "tip_force", ("q", "qd", "qdd", "base_wrench", "tip_force"),
          lambda ctx: f"q, qd, base_wrench {TARED}; gain {_base_momentum_gain(ctx):g}/s (chosen on val)",
          _base_momentum, _base_momentum_single)
_analytic("kalman-fusion", "tip_force", ("q", "qd", "qdd", "base_wrench", "tau_J", "tip_force"),
          lambda ctx: f"q, qd, base_wrench (tared), tau_J; force rate {_kalman_force_rate(ctx):g} N/sqrt(s) "
                      "(chosen on val)", _kalman, _kalman_single)
_analytic("rnea", "joint_torque", ("q", "qd", "qdd", "tau_m"), "q, qd, qdd",
          lambda r, i, ctx: r.inverse_dynamics(i.q, i.qd, i.qdd),
          lambda r, i, k, ctx: r.inverse_dynamics(i.q[k], i.qd[k], i.qdd[k]))
# Physics may use the base sensor too (PROTOCOL 4): tau = ID - J_v^T F_hat.
_analytic("rnea-bw", "joint_torque", ("q", "qd", "qdd", "base_wrench", "tau_m"), "q, qd, qdd, base_wrench",
          lambda r, i, ctx: _rnea_minus_contact(r, i.q, i.qd, i.qdd, i.base_wrench),
          lambda r, i, k, ctx: _rnea_minus_contact(r, i.q[k], i.qd[k], i.qdd[k], i.base_wrench[k]))
_analytic("rnea-bw-tared", "joint_torque", ("q", "qd", "qdd", "base_wrench", "tau_m"), f"q, qd, qdd, base_wrench {TARED}",
          lambda r, i, ctx: _rnea_minus_contact(r, i.q, i.qd, i.qdd, _tared(r, i, ctx)),
          lambda r, i, k, ctx: _rnea_minus_contact(r, i.q[k], i.qd[k], i.qdd[k], _tared(r, i, ctx)[k]))
