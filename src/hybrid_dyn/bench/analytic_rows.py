"""The analytic rows of the benchmark: physics on the nominal model, nothing trained.

Each row is declared once, here (``ROWS.register``): its name, task, the fields it
reads, and how it predicts a run (batch) and one sample (the call a user makes in a
control loop: the same library functions, an observer or filter stepped once per
call). Adding an analytic row is one ``_analytic(...)`` call in this file.

The estimator methods of ``analytic/methods.py`` get their rows from the registry
(:func:`declare_method_rows`): ``name``, the estimator with its defaults (the
bandwidth by the rule), and ``name-val``, the bandwidth chosen on the validation
split once per scenario (:func:`_chosen_on_val`), a labelled reference. Both run at the dataset's
encoder resolution (:func:`_encoder_resolution`: 0 for the legacy sensor model) and report the share of
test samples their error bar covers (``sigma_coverage``, :func:`_sigma_coverage`). The samples before a
method's first answer (its noise window, and every window its start-up check refused) are refusals, NaN
(:func:`refusals_as_nan`), scored apart from its errors (``metrics.py``, ``answered_share``).
"""
from __future__ import annotations

import numpy as np

from ..analytic.batch_run import run_batch
from ..analytic.methods import TIP_FORCE_METHODS
from ..analytic.tare import TARE_SECONDS, tare_samples, tared_base_wrench
from ..analytic.tip_force import contact_joint_torques, tip_force_from_base_wrench, tip_force_from_torques
from ..estimator import EstimatorConfig, TipForceEstimator
from .rows import ROWS, Predictor, Row

TARED = "(tared on the first 0.5 s)"  # how the inputs column says a row reads the tared base sensor
# A residual preset's prior -> the analytic row that computes it as the preset reads it (the base wrench
# tared, unless raw_sensor), for the report's hybrid-against-prior comparison: the rows declared by hand
# below, and each registered method with rows of its own and residual_prior (declare_method_rows).
PRIOR_ROWS = {"rnea": "rnea", "rnea-bw": "rnea-bw-tared", "base-wrench": "base-wrench-tared"}


def _analytic(name: str, task: str, needs: tuple, inputs, batch_fn, single_fn=None, reference=None,
              warmup_calls=None, sigma_coverage=None) -> Row:
    """Declare an analytic row: batch_fn(robot, instance, ctx) -> (T, C) and single_fn(robot, instance, k, ctx) -> (C,).

    needs: the dataset fields it reads, its target included; inputs: the results' inputs
    column, a string or ctx -> string (a value chosen on validation); reference: a reference
    row's label; warmup_calls(ctx): untimed calls first (a stream's noise window); sigma_coverage(ctx) ->
    a callable of the error bar's coverage (registry methods)."""
    def build(ds, ctx):
        robot = ctx.robot
        return Predictor(
            predict=lambda insts: [batch_fn(robot, i, ctx) for i in insts],
            single_call=(lambda inst, k: single_fn(robot, inst, k, ctx)) if single_fn else None,
            inputs=inputs(ctx) if callable(inputs) else inputs,
            warmup_calls=1 if warmup_calls is None else warmup_calls(ctx),
            sigma_coverage=None if sigma_coverage is None else sigma_coverage(ctx),
        )

    return ROWS.register(Row(name, task, "analytic", needs=needs, needs_urdf=True, build=build, reference=reference))


# The registry's methods (analytic/methods.py): two rows each. ``name`` is what TipForceEstimator does
# with its defaults: the noise window (the tare, the bandwidth by the rule of analytic/bandwidth.py),
# then the method; its single call is the user's call itself. ``name-val`` takes the bandwidth from
# the method's grid with the least validation RMSE, once per scenario (a labelled reference: the
# cost of choosing the bandwidth without the data's answers). Both run the method's own stream (its
# ``make``, a derived class included), each chosen and cached by the method's name; a fixed value replaces
# the rule, so a method that differs from its parent only in its rule shares its parent's ``name-val``.
VAL_LABEL = "bandwidth chosen on validation"


def _chosen_on_val(ctx, name: str, grid, estimate) -> float:
    """The grid value whose estimate(robot, instance, ctx, value) has the least validation RMSE (cached)."""
    key = ("chosen-on-val", name)
    if key not in ctx.cache:
        val = ctx.dataset.split("val")
        target = np.concatenate([i["tip_force"] for i in val])

        def val_rmse(value):  # over the answered samples (a refusal is NaN); inf where none is answered
            e = np.concatenate([estimate(ctx.robot, i, ctx, value) for i in val]) - target
            ok = ~np.isnan(e).all(axis=1)
            return float(np.sqrt(np.mean(e[ok] ** 2))) if ok.any() else float("inf")

        scores = {v: val_rmse(v) for v in grid}
        ctx.cache[key] = min(scores, key=scores.get)
        ctx.log(f"[bench] {ctx.scenario} {name}: validation RMSE by value "
                + ", ".join(f"{v:g}: {e:.4f}" for v, e in scores.items()) + f" -> {ctx.cache[key]:g}")
    return ctx.cache[key]


def _encoder_resolution(ctx) -> float:
    """The dataset's encoder resolution [rad]: its hardware sensors' (``sim/sensors.py``; the robot
    description's when they state none); 0 for the legacy sensor model and for data without a generator
    config (q as recorded, not quantized by the simulator: the estimator reads it as exact, as before)."""
    from ..description.spec import resolve_encoder_resolution
    from ..sim.sensors import HardwareSensors

    sensors = (ctx.dataset.meta.get("config") or {}).get("sensors")
    return 0.0 if sensors is None else resolve_encoder_resolution(HardwareSensors.from_dict(sensors).encoder.resolution, ctx.robot.spec)


def _method_run(method, robot, inst, ctx, value=None):
    """(forces (T, 3), bandwidth, sigma (T, 3) [N]) of the method over one run as the estimator runs it, at
    the dataset's encoder resolution (cached per value)."""
    key = ("method-run", method.name, inst.name, value)
    if key not in ctx.cache:
        ctx.cache[key] = run_batch(method, robot, ctx.dataset.meta["record_hz"], inst.q, inst.qd,
                                   inst.base_wrench if "base_wrench" in method.reads else None,
                                   inst.tau_J if "tau_J" in method.reads else None, TARE_SECONDS, value,
                                   encoder_resolution=_encoder_resolution(ctx), with_sigma=True)
    return ctx.cache[key]


def refusals_as_nan(forces: np.ndarray) -> np.ndarray:
    """``run_batch``'s forces (T, 3) [N] with the samples before the method's first answer as NaN (a refusal,
    ``metrics.answered``): it gives exactly 0 N up to the end of the noise window it trusts, and over the
    whole run when it trusts none, where the estimator itself declines to answer (its status is not ``ok``);
    scored as a zero force, a method that declines read as one that errs. run_batch does not return where it
    started, so a first answer of exactly 0 N on every axis counts as refused too: a stateful method's
    (``Method.stateful``) first output after the window is its initial state, 0 N, one sample per run more
    than the window."""
    forces = np.array(forces, dtype=float)
    started = np.flatnonzero(np.any(forces != 0.0, axis=1))
    forces[: started[0] if len(started) else len(forces)] = np.nan
    return forces


def _sigma_coverage(method, ctx, value=None):
    """A callable for the row's ``sigma_coverage``: of the test samples after each run's first window that
    have an error bar (a finite sigma: the estimator has a settled estimate, as when it may say ``ok``),
    the share whose error lies within 2 sigma on every axis (NaN, an empty cell, if none has)."""
    def coverage():
        n = tare_samples(ctx.dataset.meta["record_hz"], TARE_SECONDS)
        covered = []
        for inst in ctx.dataset.split("test"):
            forces, _, sigma = _method_run(method, ctx.robot, inst, ctx, value() if callable(value) else value)
            err, sig = np.abs(forces - inst.truth.get("tip_force", inst["tip_force"]))[n:], np.asarray(sigma)[n:]
            covered.append(np.all(err <= 2.0 * sig, axis=1)[np.all(np.isfinite(sig), axis=1)])
        covered = np.concatenate(covered)
        return float(np.mean(covered)) if len(covered) else float("nan")

    return coverage


def _user_call(method):
    """The user's call, per sample: a TipForceEstimator with its defaults at the data's rate and encoder
    resolution, fresh per run."""
    def call(robot, inst, k, ctx):
        if k == 0:
            ctx.cache[("estimator", method.name)] = TipForceEstimator(
                robot, method.name, EstimatorConfig(call_hz=ctx.dataset.meta["record_hz"],
                                                    encoder_resolution=_encoder_resolution(ctx)))
        kw = {name: inst[name][k] for name in method.reads}
        return ctx.cache[("estimator", method.name)].estimate_tip_force(inst.q[k], inst.qd[k], **kw)

    return call


def declare_method_rows(method) -> None:
    """The rows ``name`` and ``name-val`` of a registered method (``TIP_FORCE_METHODS.listen`` calls it)."""
    if not method.bench_rows:
        return
    if method.residual_prior:
        PRIOR_ROWS[method.name] = method.name
    needs = method.fields + ("tip_force",)
    reads = ", ".join(("q", "qd") + tuple(f"{r} (tared)" if r == "base_wrench" and method.tares else r
                                         for r in method.reads))

    def rule_inputs(ctx):
        runs = [_method_run(method, ctx.robot, i, ctx)[1] for i in ctx.dataset.split("test")]
        values = sorted({v for v in runs if v is not None})  # None: a run with no contact-free window
        shown = ("none" if not values else f"{values[0]:.3g}" if len(values) == 1
                 else f"{values[0]:.3g}-{values[-1]:.3g}")
        unclean = f"; {runs.count(None)} of {len(runs)} runs without a contact-free window" if None in runs else ""
        return f"{reads}; {method.parameter} {shown} {method.unit} (the rule, per run's window){unclean}"

    _analytic(method.name, "tip_force", needs, rule_inputs,
              lambda r, i, ctx: refusals_as_nan(_method_run(method, r, i, ctx)[0]), _user_call(method),
              warmup_calls=lambda ctx: tare_samples(ctx.dataset.meta["record_hz"], TARE_SECONDS) + 1,
              sigma_coverage=lambda ctx: _sigma_coverage(method, ctx))

    def at(robot, inst, ctx, value):
        return refusals_as_nan(_method_run(method, robot, inst, ctx, value)[0])

    def chosen(ctx):
        return _chosen_on_val(ctx, f"{method.name} {method.parameter}", method.val_grid(ctx.dataset.meta["record_hz"]), at)

    def val_single(robot, inst, k, ctx):
        if k == 0:
            ctx.cache[("estimator-val", method.name)] = TipForceEstimator(
                robot, method.name, EstimatorConfig.from_settings(  # the parameter by its declared name
                    call_hz=ctx.dataset.meta["record_hz"], encoder_resolution=_encoder_resolution(ctx),
                    **{method.parameter: chosen(ctx)}))
        kw = {name: inst[name][k] for name in method.reads}
        return ctx.cache[("estimator-val", method.name)].estimate_tip_force(inst.q[k], inst.qd[k], **kw)

    _analytic(f"{method.name}-val", "tip_force", needs,
              lambda ctx: f"{reads}; {method.parameter} {chosen(ctx):g} {method.unit} (chosen on val)",
              lambda r, i, ctx: at(r, i, ctx, chosen(ctx)), val_single, reference=VAL_LABEL,
              warmup_calls=lambda ctx: tare_samples(ctx.dataset.meta["record_hz"], TARE_SECONDS) + 1,
              sigma_coverage=lambda ctx: _sigma_coverage(method, ctx, lambda: chosen(ctx)))


def forget_method_rows(method) -> None:
    """Remove what ``declare_method_rows`` declared for ``method`` (it was unregistered)."""
    for name in (method.name, f"{method.name}-val"):
        ROWS.pop(name, None)
    if PRIOR_ROWS.get(method.name) == method.name:
        del PRIOR_ROWS[method.name]


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
# The registry's methods (Newton's law for the whole robot, and both force sensors fused).
for _method in TIP_FORCE_METHODS.values():
    declare_method_rows(_method)
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
TIP_FORCE_METHODS.listen(declare_method_rows, forget_method_rows)  # a method registered later gets its rows too
