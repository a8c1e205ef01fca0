"""The learned rows of the benchmark: one per preset of ``learn/presets.py``.

A preset already says what a row reads (its inputs and targets), whether it
needs a URDF (an analytic prior) and, by ``raw_sensor``, whether it is a
reference row; its family is declared with it (``Preset.family``). The family is the preset's, not its network
kind's (an MLP is ``seed-net`` or ``learned``, an LSTM ``seed-net`` or ``residual``). A preset declared
later gets its row too (this module listens to ``PRESETS``).

Rows are declared tip-force presets first, then joint-torque presets, each in
the order of ``PRESETS``: the order results.csv lists them in.

A row's timed single call is the code a user runs: a tip-force model through
``StreamingModel.step`` (what ``TipForceEstimator.load`` drives), fed the run's
samples in order; a joint-torque model (no streaming class) through its
single-window path ``TrainedModel.predict_window`` with the prior from
``AnalyticPrior``.
"""
from __future__ import annotations

import time

import numpy as np

from ..analytic.tare import tare_samples, tared_base_wrench
from ..errors import UsageError
from ..learn.trained_model import recorded_train_cpu
from ..learn.presets import PRESETS
from .analytic_rows import PRIOR_ROWS  # noqa: F401  (re-exported: read from here before)
from .rows import ROWS, Predictor, Row, prior_kept_text

RAW_SENSOR_LABEL = "raw sensor, untared: reference"  # a preset with raw_sensor=True (what the offset costs)
TASK_OF_TARGETS = {("tip_force",): "tip_force", ("tau_m",): "joint_torque"}


def training_summary(config: dict) -> dict:
    """How a trained model's training ended, from its config.json: convergence shown, not claimed.

    Returns ``epochs`` (epochs run), ``stopped_by`` ("patience": no validation
    improvement for ``patience`` epochs; "lr-floor": the learning rate reached its
    floor and plateaued there; "epoch-cap": ``max_epochs`` reached while still
    improving, so the model may not have converged), ``best_epoch`` (0-based index
    into ``history`` of the weights kept; -1: the untrained model was best, e.g. a
    residual that never beat its physics part), ``initial_val_loss`` (the untrained
    model's) and ``history`` (per epoch: ``epoch``, ``train_loss``, ``val_loss``,
    standardized MSE, and ``lr`` when known).

    Models trained before ``stopped_by`` and ``best_epoch`` were recorded get them
    derived, as their training loop decided: stopped early means patience ran out;
    the kept weights are the epoch of least validation loss, if it beat the
    untrained model's ``initial_val_loss``.
    """
    history = [dict(h) for h in config.get("history", [])]
    stopped_by = config.get("stopped_by")
    if stopped_by is None:
        stopped_by = "patience" if config.get("stopped_early") else "epoch-cap"
    best_epoch = config.get("best_epoch")
    if best_epoch is None:
        val = [float(h["val_loss"]) for h in history]
        val = [v if np.isfinite(v) else np.inf for v in val]  # a diverged epoch (NaN) is never the best
        best = int(np.argmin(val)) if val else -1
        initial = float(config.get("initial_val_loss", np.inf))
        best_epoch = best if best >= 0 and val[best] < initial else -1
    return {"epochs": int(config.get("epochs", len(history))), "stopped_by": str(stopped_by),
            "best_epoch": int(best_epoch), "initial_val_loss": config.get("initial_val_loss"), "history": history}


def learned_predictor(model, train_seconds: float, inputs: str | None = None) -> Predictor:
    """The row of a trained model: batch predictions, the user's single call, how training ended."""
    single, warmup = user_single_call(model)
    training = training_summary(model.config)
    # A net on a physics prior starts as the prior (a zero output layer) and keeps it when no epoch
    # beats it on validation (best_epoch -1): the whole prior, every output at once.
    kept = None if model.preset.prior is None else prior_kept_text([training["best_epoch"] == -1])
    return Predictor(predict=model.predict, single_call=single, warmup_calls=warmup,
                     train_seconds=float(train_seconds), train_cpu_seconds=recorded_train_cpu(model),
                     n_params=int(model.n_params),
                     inputs=", ".join(model.config.get("inputs", [])) if inputs is None else inputs,
                     training=training, prior_kept=kept)


def user_single_call(model):
    """(call(inst, k), warm-up calls): the per-sample path a user runs with this model."""
    if list(model.targets) == ["tip_force"]:
        return _streaming_call(model)
    return _window_call(model), 1


def _streaming_call(model):
    """``StreamingModel.step`` at the model's record rate, restarted at each run's first sample
    (k = 0) and fed it in order, as ``TipForceEstimator`` feeds it (the sample already validated)."""
    from ..learn.stream_predictor import StreamingModel

    stream = StreamingModel(model, call_hz=float(model.config["record_hz"]))

    def call(inst, k):
        if k == 0:
            stream.reset()
        return stream.step(inst.q[k], inst.qd[k], inst.qdd[k],
                           inst.base_wrench[k] if "base_wrench" in inst.fields else None,
                           inst.tau_J[k] if "tau_J" in inst.fields else None, None)[0]

    return call, stream.warmup_calls(stream.call_hz)


def _window_call(model):
    """``TrainedModel.predict_window`` on the run's edge-padded window ending at sample k, with the
    prior from ``AnalyticPrior.single`` (on the base wrench tared on the run's start, where it tares)."""
    from ..data.input_windows import concat_fields, window_index

    windows, tared = {}, {}

    def call(inst, k):
        if inst.name not in windows:
            windows[inst.name] = (concat_fields(model.sensor_view([inst]), model.inputs).astype(np.float64),
                                  window_index([len(inst)], model.window))
        x_all, index = windows[inst.name]
        prior, p = None, model.prior
        if p is not None and p.tare_seconds > 0:
            if inst.name not in tared:  # the tare is per run: its offset comes from the run's start
                tared[inst.name] = tared_base_wrench(p.robot, inst.q, inst.qd, inst.qdd, inst.base_wrench,
                                                     tare_samples(p.record_hz, p.tare_seconds))
            prior = p.single({"q": inst.q[k], "qd": inst.qd[k], "qdd": inst.qdd[k], "base_wrench": tared[inst.name][k]})
        return model.predict_window(x_all[index[k]], prior=prior)

    return call


def _build(preset: str):
    def build(ds, ctx):
        from ..learn import train_model

        t0 = time.perf_counter()
        # the profile's preset_overrides (a study's capacity arm) change the preset, not the row's name
        model = train_model(ds, ctx.plan.preset(preset), ctx.work_dir / "models" / preset,
                            config=ctx.plan.train_config(), wait=True)  # another bench sharing runs/: wait, reuse
        return learned_predictor(model, getattr(model, "train_seconds", None) or (time.perf_counter() - t0))

    return build


def declare_preset_row(p) -> None:
    """The row of preset ``p`` (``PRESETS.register`` tells this module of a later one)."""
    task = TASK_OF_TARGETS.get(tuple(p.targets))
    if task is None:
        raise UsageError(f"preset {p.name!r} predicts neither the tip force nor tau_m: no bench task for it")
    ROWS.register(Row(p.name, task, p.family, needs=tuple(p.inputs) + tuple(p.targets),
                needs_urdf=p.prior is not None, build=_build(p.name), trains=True,
                reference=RAW_SENSOR_LABEL if p.raw_sensor else None,
                prior_row=None if p.raw_sensor else PRIOR_ROWS.get(p.prior)))


def forget_preset_row(p) -> None:
    ROWS.pop(p.name, None)


def _declare_presets() -> None:
    presets = list(PRESETS.values())
    odd = [p.name for p in presets if tuple(p.targets) not in TASK_OF_TARGETS]
    if odd:
        raise UsageError(f"presets {odd} predict neither the tip force nor tau_m: no bench task for them")
    for task in ("tip_force", "joint_torque"):  # the order results.csv lists them in
        for p in presets:
            if TASK_OF_TARGETS[tuple(p.targets)] == task:
                declare_preset_row(p)


_declare_presets()
PRESETS.listen(declare_preset_row, forget_preset_row)


# ---------------------------------------------------------------- Gaussian process
def _build_gp(ds, ctx):
    """One exact GP per joint (``learn/gp.py``), fitted on the train split, its hyperparameters by
    marginal likelihood; cached in the work dir like the nets, no loss curve (no epochs)."""
    from ..learn.gp import GPConfig, train_gp

    t0 = time.perf_counter()
    model = train_gp(ds, ctx.work_dir / "models" / "gp", GPConfig(seed=ctx.profile.seed), wait=True)
    return gp_predictor(model, t0)


def gp_predictor(model, t0: float, **fields) -> Predictor:
    """The row of a fitted GP (plain or residual): batch predictions and, per call, the model's own
    per-sample path (one row of its inputs); ``t0``: when its build began (the training time when the
    model file does not record one); ``fields``: other Predictor fields."""
    x_of = {}

    def single(inst, k):
        if inst.name not in x_of:
            x_of[inst.name] = np.concatenate([np.asarray(inst[f], float).reshape(len(inst), -1)
                                              for f in model.inputs], axis=1)
        return model.predict_rows(x_of[inst.name][k:k + 1])[0]

    seconds = model.train_seconds
    return Predictor(predict=model.predict, single_call=single,
                     train_seconds=float(seconds if np.isfinite(seconds) else time.perf_counter() - t0),
                     train_cpu_seconds=recorded_train_cpu(model), n_params=int(model.n_params),
                     **{"inputs": ", ".join(model.inputs), **fields})


ROWS.register(Row("gp", "joint_torque", "gp", needs=("q", "qd", "qdd", "tau_m"), needs_urdf=False, build=_build_gp))
