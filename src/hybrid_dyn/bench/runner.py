"""The benchmark harness: every model family on the same data, one results table.

For each scenario of a profile: make (or reuse) the dataset, then for each
model row build a predictor (analytic rows: nothing to train; learned rows:
train or reuse), predict every sample of the validation and test splits, and
score all rows with the same metrics (``metrics.py``) against the same logged
targets. A row that fails is written with its error, not dropped.

Targets: tip force -> the logged ``tip_force``; joint torque -> the logged
commanded motor torque ``tau_m`` (friction included), as PROTOCOL 4 says.
Losses are MSE on targets standardised with the train split's statistics, for
analytic and learned rows alike. Sequence models are scored on every sample:
their first L-1 windows of each instance are edge-padded (``data/windows.py``),
exactly as a streaming estimator starts up.
"""
from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import os
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from tqdm.auto import tqdm

from ..analytic.base_momentum import BaseMomentumObserver, base_momentum_tip_force
from ..analytic.kalman import KalmanTipForce, tare_window_noise
from ..analytic.momentum_observer import MomentumObserver
from ..analytic.robot import Robot, load_robot
from ..analytic.tare import TARE_SECONDS, tare_samples, tared_base_wrench
from ..analytic.tip_force import contact_joint_torques, tip_force_from_base_wrench, tip_force_from_torques
from ..data import Dataset
from .metrics import ErrorReport, base_force_noise_rms, standardized_mse
from ..outputs import output_lock, refuse_foreign, unique_temp
from .profiles import BenchProfile

TASK_TARGET = {"tip_force": "tip_force", "joint_torque": "tau_m"}

COLUMNS = [
    "task", "scenario", "model", "family", "inputs", "status",
    "val_loss", "test_loss", "rmse", "nmse", "rmse_contact", "rmse_free", "max_error",
    "rmse_1", "rmse_2", "rmse_3", "rmse_4", "rmse_5", "rmse_6", "rmse_7", "noise_rms",
    "train_seconds", "infer_us_per_sample", "infer_us_per_call", "n_params", "n_test_samples",
    "epochs", "stopped_by", "best_epoch",  # learned rows only (``training_summary``); empty for analytic rows
    "error",
]


@dataclass
class Predictor:
    """What the harness needs from any model: batch predictions per instance and one timed single call."""

    predict: Callable[[list], list]  # instances -> list of (T, C) arrays in physical units
    single_call: Callable[[object, int], np.ndarray] | None = None  # (instance, k) -> (C,)
    train_seconds: float = 0.0
    n_params: int = 0
    inputs: str = ""
    training: dict | None = None  # learned rows: ``training_summary`` of the model's config


@dataclass
class RowSpec:
    task: str
    model: str
    family: str  # analytic | identified | seed-net | residual | delan
    build: Callable[[Dataset, "BenchContext"], Predictor]


@dataclass
class BenchContext:
    profile: BenchProfile
    scenario: str
    dataset: Dataset
    robot: Robot | None  # the nominal model every analytic part uses (None: no URDF for this arm)
    work_dir: Path
    data_root: Path = Path("data")
    log: Callable[[str], None] = print
    cache: dict = field(default_factory=dict)


# ---------------------------------------------------------------- analytic rows
def _analytic(task: str, name: str, inputs: str, batch_fn, single_fn=None) -> RowSpec:
    """An analytic row: batch_fn(robot, instance, ctx) and single_fn(robot, instance, k, ctx)."""
    def build(ds, ctx):
        robot = ctx.robot
        return Predictor(
            predict=lambda insts: [batch_fn(robot, i, ctx) for i in insts],
            single_call=(lambda inst, k: single_fn(robot, inst, k, ctx)) if single_fn else None,
            inputs=inputs(ctx) if callable(inputs) else inputs,
        )

    return RowSpec(task, name, "analytic", build)


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
    """A row's timed single call: one observer per scenario (``make(robot, ctx)``), stepped once per
    call on ``sensor(robot, inst, ctx)`` (its (T, k) input), as a control loop runs it."""
    def single(robot, inst, k, ctx):
        obs = ctx.cache.get(name)
        if obs is None:
            obs = ctx.cache[name] = make(robot, ctx)
            obs.step(inst.q[0], inst.qd[0], sensor(robot, inst, ctx)[0])
        return obs.step_force(inst.q[k], inst.qd[k], sensor(robot, inst, ctx)[k])

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
    """One filter per scenario, stepped once per call."""
    kf = ctx.cache.get("kalman-fusion")
    if kf is None:
        kf = ctx.cache["kalman-fusion"] = _kalman_filter(robot, inst, ctx)
    return kf.step(inst.q[k], inst.qd[k], _tared(robot, inst, ctx)[k], inst.tau_J[k])


ANALYTIC_ROWS = {
    "torques-pinv": _analytic(
        "tip_force", "torques-pinv", "q, qd, qdd, tau_J",
        lambda r, i, ctx: tip_force_from_torques(r, i.q, i.qd, i.qdd, i.tau_J),
        lambda r, i, k, ctx: tip_force_from_torques(r, i.q[k], i.qd[k], i.qdd[k], i.tau_J[k])),
    "base-wrench": _analytic(
        "tip_force", "base-wrench", "q, qd, qdd, base_wrench",
        lambda r, i, ctx: tip_force_from_base_wrench(r, i.q, i.qd, i.qdd, i.base_wrench),
        lambda r, i, k, ctx: tip_force_from_base_wrench(r, i.q[k], i.qd[k], i.qdd[k], i.base_wrench[k])),
    "momentum-observer": _analytic(
        "tip_force", "momentum-observer", lambda ctx: f"q, qd, tau_J; gain {_momentum_gain(ctx):g}/s (chosen on val)",
        _momentum, _momentum_single),
    "rnea": _analytic(
        "joint_torque", "rnea", "q, qd, qdd",
        lambda r, i, ctx: r.inverse_dynamics(i.q, i.qd, i.qdd),
        lambda r, i, k, ctx: r.inverse_dynamics(i.q[k], i.qd[k], i.qdd[k])),
    # Physics may use the base sensor too (PROTOCOL 4): tau = ID - J_v^T F_hat.
    "rnea-bw": _analytic(
        "joint_torque", "rnea-bw", "q, qd, qdd, base_wrench",
        lambda r, i, ctx: _rnea_minus_contact(r, i.q, i.qd, i.qdd, i.base_wrench),
        lambda r, i, k, ctx: _rnea_minus_contact(r, i.q[k], i.qd[k], i.qdd[k], i.base_wrench[k])),
    # The same two with the base sensor tared on each instance's contact-free start (analytic/tare.py).
    "base-wrench-tared": _analytic(
        "tip_force", "base-wrench-tared", "q, qd, qdd, base_wrench (tared on the first 0.5 s)",
        lambda r, i, ctx: tip_force_from_base_wrench(r, i.q, i.qd, i.qdd, _tared(r, i, ctx)),
        lambda r, i, k, ctx: tip_force_from_base_wrench(r, i.q[k], i.qd[k], i.qdd[k], _tared(r, i, ctx)[k])),
    "rnea-bw-tared": _analytic(
        "joint_torque", "rnea-bw-tared", "q, qd, qdd, base_wrench (tared on the first 0.5 s)",
        lambda r, i, ctx: _rnea_minus_contact(r, i.q, i.qd, i.qdd, _tared(r, i, ctx)),
        lambda r, i, k, ctx: _rnea_minus_contact(r, i.q[k], i.qd[k], i.qdd[k], _tared(r, i, ctx)[k])),
    # Issue 16: Newton's law for the whole robot (no qdd), and both force sensors fused.
    "base-momentum": _analytic(
        "tip_force", "base-momentum", lambda ctx: "q, qd, base_wrench (tared on the first 0.5 s); gain "
        f"{_base_momentum_gain(ctx):g}/s (chosen on val)", _base_momentum, _base_momentum_single),
    "kalman-fusion": _analytic(
        "tip_force", "kalman-fusion", lambda ctx: "q, qd, base_wrench (tared), tau_J; force rate "
        f"{_kalman_force_rate(ctx):g} N/sqrt(s) (chosen on val)", _kalman, _kalman_single),
}


# ----------------------------------------------------------------- learned rows
def _learned(task: str, preset: str, family: str) -> RowSpec:
    def build(ds, ctx):
        from ..learn import train_model

        out = ctx.work_dir / "models" / preset
        t0 = time.perf_counter()
        model = train_model(ds, preset, out, config=ctx.profile.train_config())
        train_seconds = getattr(model, "train_seconds", None) or (time.perf_counter() - t0)
        return Predictor(
            predict=model.predict,
            single_call=_learned_single_call(model),
            train_seconds=float(train_seconds),
            n_params=int(model.n_params),
            inputs=", ".join(model.config.get("inputs", [])),
            training=training_summary(model.config),
        )

    return RowSpec(task, preset, family, build)


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


def _learned_single_call(model):
    """One prediction at sample k through the model's single-window path, as a control loop calls it.

    The window is the edge-padded one the batch path uses; a momentum prior is
    an observer stepped once per call, as in the streaming estimator.
    """
    from ..data.windows import concat_fields, window_index

    windows, observers, tared = {}, {}, {}

    def call(inst, k):
        if inst.name not in windows:
            windows[inst.name] = (concat_fields(model.sensor_view([inst]), model.inputs).astype(np.float64),
                                  window_index([len(inst)], model.window))
        x_all, index = windows[inst.name]
        prior, w = None, None
        p = model.prior
        if p is not None and p.tare_seconds > 0:
            # The tare is per run: its offset comes from the instance's start, as in training.
            if inst.name not in tared:
                tared[inst.name] = tared_base_wrench(p.robot, inst.q, inst.qd, inst.qdd, inst.base_wrench,
                                                     tare_samples(p.record_hz, p.tare_seconds))
            w = tared[inst.name][k]
        if model.preset.prior in ("momentum", "base-momentum"):
            obs = observers.get(inst.name)
            if obs is None:
                observer = MomentumObserver if model.preset.prior == "momentum" else BaseMomentumObserver
                obs = observers[inst.name] = observer(model.robot, model.config.get("observer_gain", 20.0),
                                                      1.0 / model.config["record_hz"])
            prior = obs.step_force(inst.q[k], inst.qd[k], inst.tau_J[k] if model.preset.prior == "momentum" else w)
        elif w is not None:
            prior = p.single({"q": inst.q[k], "qd": inst.qd[k], "qdd": inst.qdd[k], "base_wrench": w})
        return model.predict_window(x_all[index[k]], prior=prior)

    return call


def learned_family(preset: str) -> str:
    if preset.startswith("seed-"):
        return "seed-net"
    if preset.startswith("residual"):
        return "residual"
    if preset.startswith("delan"):
        return "delan" if preset in ("delan", "delan-friction") else "residual"
    return "learned"


def row_specs(profile: BenchProfile) -> list[RowSpec]:
    rows = []
    for name in profile.analytic_rows:
        rows.append(ANALYTIC_ROWS[name])
    for preset in profile.tip_models:
        rows.append(_learned("tip_force", preset, learned_family(preset)))
    for preset in profile.torque_models:
        rows.append(_learned("joint_torque", preset, learned_family(preset)))
    for spec in profile.extra_rows():
        rows.append(spec)
    return rows


# ---------------------------------------------------------------------- scoring
def _median_call_us(fn, inst, n_calls: int = 200) -> float:
    n = len(inst)
    ks = np.linspace(0, n - 1, min(n, n_calls)).astype(int)
    fn(inst, int(ks[0]))  # warm-up (lazy allocations, first-call costs)
    times = []
    for k in ks:
        t0 = time.perf_counter()
        fn(inst, int(k))
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e6)


def score_row(spec: RowSpec, ctx: BenchContext, norm: dict) -> dict:
    ds = ctx.dataset
    target = TASK_TARGET[spec.task]
    row = {"task": spec.task, "scenario": ctx.scenario, "model": spec.model, "family": spec.family}
    if target not in ds.fields:
        raise ValueError(f"the dataset has no {target!r} field")
    pred_obj = spec.build(ds, ctx)
    row.update(inputs=pred_obj.inputs, train_seconds=pred_obj.train_seconds, n_params=pred_obj.n_params)
    if pred_obj.training is not None:
        t = pred_obj.training
        row.update(epochs=t["epochs"], stopped_by=t["stopped_by"], best_epoch=t["best_epoch"])
        row["curve"] = {"task": spec.task, **t}  # not a results.csv column: the runner keeps it in curves.json
    mean, std = norm[target]
    losses = {}
    for split in ("val", "test"):
        insts = ds.split(split)
        tgt = np.concatenate([i[target] for i in insts])  # also loads the files: I/O stays out of the timing
        t0 = time.perf_counter()
        preds = pred_obj.predict(insts)
        elapsed = time.perf_counter() - t0
        pred = np.concatenate(preds)
        losses[split] = standardized_mse(pred, tgt, mean, std)
        if split == "test":
            f_truth = (np.concatenate([i.truth.get("tip_force", i["tip_force"]) for i in insts])
                       if "tip_force" in ds.fields else None)
            report = ErrorReport.compute(pred, tgt, f_truth)
            if spec.task == "tip_force" and "base_wrench" in ds.fields:
                if "base-force-noise" not in ctx.cache:  # a property of the data: once per scenario
                    ctx.cache["base-force-noise"] = base_force_noise_rms(insts)
                row["noise_rms"] = ctx.cache["base-force-noise"]
            row["infer_us_per_sample"] = elapsed / len(pred) * 1e6
            ctx.cache[(spec.task, spec.model)] = preds
    row.update(val_loss=losses["val"], test_loss=losses["test"], rmse=report.rmse, nmse=report.nmse,
               rmse_contact=report.rmse_contact, rmse_free=report.rmse_free, max_error=report.max_error,
               n_test_samples=report.n_samples)
    for j, v in enumerate(report.per_component):
        row[f"rmse_{j + 1}"] = float(v)
    if pred_obj.single_call is not None:
        row["infer_us_per_call"] = _median_call_us(pred_obj.single_call, ds.split("test")[0])
    row["status"] = "ok"
    return row


def train_split_stats(ds: Dataset) -> dict:
    """Per-component mean and std of each target over the train split (std floored)."""
    out = {}
    for target in TASK_TARGET.values():
        if target in ds.fields:
            y = np.concatenate([i[target] for i in ds.split("train")])
            out[target] = (y.mean(0), np.maximum(y.std(0), 1e-6))
    return out


# ------------------------------------------------------------------ the results
def write_results(path: Path, rows: list[dict]) -> None:
    """results.csv with the stable column set, written atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = unique_temp(path)
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: _fmt(r.get(k, "")) for k in COLUMNS})
    os.replace(tmp, path)


CURVES_FILE = "curves.json"  # beside results.csv: the learned rows' loss curves


def write_curves(path: Path, rows: list[dict]) -> None:
    """The learned rows' loss curves, ``{scenario: {model: {task, epochs, stopped_by, best_epoch,
    initial_val_loss, history}}}`` (``training_summary``), written atomically, so the report's learning-curve
    figures can be redrawn from files."""
    curves: dict = {}
    for r in rows:
        if r.get("curve") is not None:
            curves.setdefault(r["scenario"], {})[r["model"]] = r["curve"]
    _write_json(Path(path), curves)


def read_curves(path: Path) -> dict:
    """curves.json as ``write_curves`` wrote it; {} when there is none (a report without learned rows)."""
    path = Path(path)
    return json.loads(path.read_text()) if path.is_file() else {}


def read_results(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _fmt(v):
    if isinstance(v, float):
        return "" if np.isnan(v) else f"{v:.6g}"
    return v


def _train_job(args) -> tuple[str, str | None]:
    """Train one learned row in a worker process (single-threaded torch)."""
    dataset_path, preset, out_dir, train_config, threads = args
    _set_torch_threads(threads)
    from ..learn import train_model

    try:
        train_model(dataset_path, preset, out_dir, config=train_config)
        return preset, None
    except Exception as err:  # reported again, with its row, when the row is scored
        return preset, f"{type(err).__name__}: {err}"


def pretrain(jobs: list, workers: int, log=print) -> None:
    """Train the learned rows in parallel, one single-threaded model per process.

    Each model's training is seeded on its own, so the result does not depend
    on the worker count or the order; finished models are reused on a rerun.
    The workers die with this process, and an interrupt stops them instead of
    waiting for every queued model (``process_pool``).
    """
    if not jobs:
        return
    if workers <= 1:
        for job in tqdm(jobs, desc="training", unit="model"):
            preset, err = _train_job(job)
            if err:
                log(f"[bench] training {preset} failed: {err}")
        return
    from concurrent.futures import as_completed

    from ..sim.executors import process_pool

    with process_pool(workers) as pool:
        futures = [pool.submit(_train_job, job) for job in jobs]
        for fut in tqdm(as_completed(futures), total=len(futures), desc="training", unit="model"):
            preset, err = fut.result()
            if err:
                log(f"[bench] training {preset} failed: {err}")


def _set_torch_threads(n: int) -> None:
    try:
        import torch
    except ImportError:  # pragma: no cover
        return
    torch.set_num_threads(n)


def run_bench(profile: BenchProfile, out_dir, data_root=None, work_root=None, dataset_provider=None,
              log: Callable[[str], None] = print) -> list[dict]:
    """Run every row of ``profile`` on every scenario; write ``out_dir/results.csv`` and the report.

    dataset_provider(scenario, profile) -> Dataset; default: generate with the
    DART generator, cached by config hash under ``data_root``.
    Models and datasets are reused on rerun (same config and data checksum),
    so an interrupted bench resumes where it stopped. ``out_dir`` must be new,
    empty or an earlier report of the bench (its ``run.json``); it is locked
    for the run.
    """
    # The study's networks are tiny: torch's intra-op threads cost more than they
    # give, and on a busy machine they spin (measured: a 2x32 MLP step 0.8 ms on
    # one thread, 118 ms on two with the cores oversubscribed). The bench owns its
    # process, so it pins torch to ``profile.torch_threads``.
    _set_torch_threads(profile.torch_threads)
    out_dir = Path(out_dir)
    with output_lock(out_dir, "report folder"):  # one bench per report folder at a time
        previous = _claim_report_dir(out_dir)
        return _run_bench_locked(profile, out_dir, previous, data_root, work_root, dataset_provider, log)


def _claim_report_dir(out_dir: Path) -> list[dict]:
    """Make ``out_dir`` a report folder of this toolkit, or refuse; returns its earlier invocations.

    A folder is the bench's when its ``run.json`` says so (a ``"bench_report"``
    key, or the ``profile`` of reports written before that key); an empty or new folder is claimed by writing that marker before
    anything else, so a run killed halfway still leaves a folder a rerun may
    use. Anything else (a user's README.md or results.csv) is refused, named.
    """
    from ..errors import OutputPathError

    if out_dir.exists() and not out_dir.is_dir():
        raise OutputPathError(f"report folder {out_dir} exists and is not a directory")
    marker = out_dir / "run.json"
    if marker.is_file():
        try:
            old = json.loads(marker.read_text())
        except (OSError, ValueError):
            old = None
        if not isinstance(old, dict) or not ("bench_report" in old or "profile" in old):
            refuse_foreign(marker, "benchmark report", "it is not a run.json of hybrid-dyn bench")
        if "invocations" in old:
            return list(old["invocations"])
        return [{"wall_seconds": old.get("wall_seconds")}]  # a report from before invocations were kept
    present = sorted(p.name for p in out_dir.iterdir()) if out_dir.is_dir() else []
    if present:
        refuse_foreign(out_dir, "benchmark report",
                       f"it holds {', '.join(present[:5])}{' ...' if len(present) > 5 else ''} but no run.json")
    out_dir.mkdir(parents=True, exist_ok=True)
    _write_json(marker, {"bench_report": 1, "invocations": []})
    return []


def _write_json(path: Path, obj: dict) -> None:
    tmp = unique_temp(path)
    tmp.write_text(json.dumps(obj, indent=1, default=str))
    os.replace(tmp, path)


def work_dir(profile: BenchProfile, scenario: str, ds: Dataset, work_root: Path) -> Path:
    """Where a profile's models of one scenario are cached: one folder per dataset and training
    recipe, so a run with another recipe never meets these models."""
    recipe = hashlib.sha256(json.dumps(profile.train_config().fingerprint_fields(), sort_keys=True).encode())
    return Path(work_root) / profile.name / scenario / f"{ds.checksum[:12]}-train-{recipe.hexdigest()[:8]}"


def _run_bench_locked(profile, out_dir, previous, data_root, work_root, dataset_provider, log) -> list[dict]:
    from .report import write_report

    data_root = Path(data_root or os.environ.get("HYBRID_DYN_DATA", "data"))
    work_root = Path(work_root or os.environ.get("HYBRID_DYN_RUNS", "runs"))
    provider = dataset_provider or (lambda scenario, prof: prof.dataset(scenario, data_root, log=log))
    rows: list[dict] = []
    datasets = {}
    contexts = {}
    t_start = time.perf_counter()
    for scenario in profile.scenarios:
        log(f"[bench] scenario {scenario}: dataset")
        ds = provider(scenario, profile)
        datasets[scenario] = ds
        # Real logs of arms without a description have no analytic model (their rows are skipped).
        from ..description import available_robots

        robot = load_robot(ds.meta["robot"]) if ds.meta.get("robot") in available_robots() else None
        ctx = BenchContext(profile, scenario, ds, robot, work_dir(profile, scenario, ds, work_root),
                           data_root, log=log)
        contexts[scenario] = ctx
        norm = train_split_stats(ds)
        specs = [s for s in row_specs(profile) if TASK_TARGET[s.task] in ds.fields and profile.applies(s, ds)]
        # Parallel workers train quietly (one progress bar over the models, not one per process).
        tcfg = profile.train_config()
        if profile.workers > 1:
            tcfg = dataclasses.replace(tcfg, progress=False)
        jobs = [(str(ds.path), s.model, str(ctx.work_dir / "models" / s.model), tcfg, profile.torch_threads)
                for s in specs if s.family not in ("analytic", "identified")]
        log(f"[bench] {scenario}: training {len(jobs)} learned models on {profile.workers} workers")
        pretrain(jobs, profile.workers, log=log)
        for spec in tqdm(specs, desc=f"bench {scenario}", unit="model"):
            t0 = time.perf_counter()
            try:
                row = score_row(spec, ctx, norm)
            except Exception as err:  # a failed model is a row, not a crash
                row = {"task": spec.task, "scenario": scenario, "model": spec.model, "family": spec.family,
                       "status": "failed", "error": f"{type(err).__name__}: {err}"}
                log(f"[bench] {spec.model} FAILED: {err}\n{traceback.format_exc(limit=3)}")
            rows.append(row)
            write_results(out_dir / "results.csv", rows)
            write_curves(out_dir / CURVES_FILE, rows)
            log(f"[bench] {scenario} {spec.task:12s} {spec.model:22s} rmse={row.get('rmse', float('nan')):.4g} "
                f"({time.perf_counter() - t0:.1f} s)" if row["status"] == "ok" else
                f"[bench] {scenario} {spec.model} failed")
    wall = time.perf_counter() - t_start
    # Keep every invocation (``previous``, read when the folder was claimed): a rerun
    # that reuses cached data and models is fast, and the first, full run's wall
    # time must not be overwritten by it.
    invocations = previous + [{"finished": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "wall_seconds": wall,
                               "rows": len(rows), "rows_ok": sum(r.get("status") == "ok" for r in rows)}]
    meta = {"bench_report": 1, "profile": profile.to_dict(), "wall_seconds": wall, "invocations": invocations,
            "datasets": {s: {"path": str(d.path), "checksum": d.checksum, "seed": d.meta.get("seed"),
                             "config_hash": d.meta.get("config_hash")} for s, d in datasets.items()}}
    _write_json(out_dir / "run.json", meta)
    write_report(out_dir, rows, meta, contexts)
    return rows
