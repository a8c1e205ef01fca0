"""Training: Adam on standardized MSE, a learning-rate schedule, early stopping; deterministic and resumable.

The design in full: ``docs/design/learn.md`` (train.py).
"""
from __future__ import annotations

import contextlib
import hashlib
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from ..analytic.tare import tared_runs
from ..data import Dataset, load_dataset
from ..data.splits import first_instances
from ..data.input_windows import WindowedSplit
from ..errors import UsageError
from ..outputs import output_lock
from .checkpoints import _load_checkpoint, _restore_optimizer, _save_checkpoint
from .trained_model import (MODEL_FORMAT, MODEL_FORMAT_VERSION, HybridModel, ModelError, TrainedModel, canonical_json,
                    check_instances, load_model, save_model)
from .kinds import clips_gradients  # declared with the network kind
from .model_folder import _refuse_foreign_files, _reuse
from .presets import PRESETS, Preset
from .priors import AnalyticPrior
from .recipes import TrainConfig, _option, budget_lr, improvement_needed
from .training_data import _batches, _check_robot_and_widths, _stats, evaluate_split, field_widths

STOP_REASONS = ("patience", "lr-floor", "epoch-cap", "budget")


def _device(name: str) -> torch.device:
    """The torch device for TrainConfig.device; a CUDA device that is not there is refused, not replaced."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    dev = torch.device(name)
    if dev.type == "cuda":
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if (dev.index or 0) >= count:
            raise UsageError(f"{_option('device')} is {name!r}, but this PyTorch ({torch.__version__}) sees "
                             f"{count} CUDA device(s); use cpu or auto")
    return dev


@contextlib.contextmanager
def _deterministic(num_threads: int | None = None):
    """Deterministic algorithms (and the thread count) for the duration of training,
    then the caller's settings back."""
    before, threads = torch.are_deterministic_algorithms_enabled(), torch.get_num_threads()
    torch.use_deterministic_algorithms(True, warn_only=True)
    if num_threads:
        torch.set_num_threads(num_threads)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(before)
        torch.set_num_threads(threads)


# ------------------------------------------------------------------ training
def run_fingerprint(preset: Preset, config: TrainConfig, dataset_checksum: str) -> str:
    return hashlib.sha256(canonical_json({"preset": preset.fingerprint_dict(), "train": config.fingerprint_fields(),
                                          "dataset": dataset_checksum}).encode()).hexdigest()


def train_model(dataset, preset, out_dir, config: TrainConfig | None = None, wait: bool = False) -> TrainedModel:
    """Train ``preset`` (a name or a :class:`Preset`) on ``dataset`` (a Dataset or its path).

    Writes the model to ``out_dir``. A finished model of the same run there is
    returned as is; a checkpoint of the same run is resumed; anything of another
    run there is an error (nothing is overwritten). ``wait``: when another run is
    training into ``out_dir``, wait for it (and reuse its model) instead of refusing.
    """
    config = config or TrainConfig()
    config.validate()  # a caller may have changed a field since construction
    device = _device(config.device)
    preset = PRESETS.lookup(preset) if isinstance(preset, str) else preset
    config = config.for_preset(preset)  # the budget the run will spend is part of its fingerprint
    ds: Dataset = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
    out_dir = Path(out_dir)
    fingerprint = run_fingerprint(preset, config, ds.checksum)
    if (out_dir / "config.json").is_file():  # a finished model is never written again: no lock needed to read it
        return _reuse(out_dir, fingerprint)
    with output_lock(out_dir, "model folder", wait=wait):
        if (out_dir / "config.json").is_file():  # finished by another run between the check and the lock
            return _reuse(out_dir, fingerprint)
        _refuse_foreign_files(out_dir)
        return _train_locked(ds, preset, out_dir, config, fingerprint, device)



def _train_locked(ds: Dataset, preset: Preset, out_dir: Path, config: TrainConfig, fingerprint: str,
                  device) -> TrainedModel:
    """Checks of robot and data first (nothing is written before they pass), then training."""
    from ..description import ROBOTS, has_description

    robot_name = ds.meta.get("robot")
    if not robot_name:
        raise ModelError(f"dataset {ds.path} does not name its robot")
    train, val = ds.split("train"), ds.split("val")
    if not train or not val:
        raise ModelError(f"dataset {ds.path} needs instances in its train and val splits")
    if config.train_instances is not None:
        train, val = first_instances(train, val, config.train_instances, ds.path)
    missing = sorted((set(preset.inputs) | set(preset.targets)) - set(ds.fields))
    if missing:
        raise ModelError(f"dataset {ds.path} lacks fields {missing} that preset {preset.name!r} needs")
    robot = None
    sensor_tare = sensor_tare_seconds(preset, config)
    if has_description(robot_name):
        from ..analytic.robot import load_robot

        # The robot of the prior and of the sensor tare: what TrainedModel.robot loads again.
        robot = load_robot(robot_name, params=config.analytic_params)
    elif preset.prior is not None:
        raise ModelError(f"preset {preset.name!r} needs a description of robot {robot_name!r} (dataset {ds.path}) "
                         f"for its analytic part, and there is none (available: {', '.join(ROBOTS.names(data_only=False))}); "
                         f"a data-only preset (seed nets, DeLaN) needs none")
    elif sensor_tare > 0:
        raise ModelError(f"preset {preset.name!r} reads the base wrench, tared with the model of robot "
                         f"{robot_name!r} (dataset {ds.path}), and this toolkit has no description of it: give a URDF "
                         f"(see docs/bring_your_own_log.md) or train on the raw sensor with tare_seconds=0")

    prior = None
    if preset.prior is not None:
        prior = AnalyticPrior(preset.prior, robot, ds.meta.get("record_hz"), config.observer_gain,
                              config.tare_seconds)
    needed = set(preset.inputs) | set(preset.targets) | (set(prior.fields) if prior else set())
    missing = sorted(needed - set(ds.fields))
    if missing:
        raise ModelError(f"dataset {ds.path} lacks fields {missing} that the analytic part of {preset.name!r} needs")
    all_widths = field_widths(train[0], sorted(needed))
    _check_robot_and_widths(ds, all_widths, robot)
    check_instances(train + val, needed, all_widths, f"preset {preset.name!r}")  # every instance as the first
    widths = {f: all_widths[f] for f in dict.fromkeys(preset.inputs + preset.targets)}
    out_dir.mkdir(parents=True, exist_ok=True)

    def split_data(instances):
        extra = None
        if prior is not None:  # the prior tares its own copy of the wrench (the same definition)
            extra = {"prior": prior.compute_instances(instances, out_dir / "analytic_cache", ds.checksum)}
        seen = tared_runs(instances, robot, ds.meta.get("record_hz"), sensor_tare)
        return WindowedSplit(seen, preset.window, list(preset.inputs), list(preset.targets), extra=extra)

    cpu0 = time.process_time()  # training's CPU time includes the windows and the prior (process: every thread)
    ws_train, ws_val = split_data(train), split_data(val)
    x_mean, x_std = _stats(ws_train.x)
    y_mean, y_std = _stats(ws_train.y)

    with _deterministic(config.num_threads):
        torch.manual_seed(config.seed)
        module = HybridModel(preset, widths)
        module.set_normalization(x_mean, x_std, y_mean, y_std)
        module.to(device)
        opt = _optimizer(module, config)
        return _fit(module, opt, preset, config, ds, ws_train, ws_val, out_dir, fingerprint, widths, prior, device,
                    sensor_tare, cpu0)


def _optimizer(module: torch.nn.Module, config: TrainConfig) -> torch.optim.Optimizer:
    """Adam, or AdamW where the config decays weights.

    Decoupled decay (AdamW) shrinks every weight at the same relative rate, where an L2 term in the
    loss would pass through Adam's per-parameter scaling. Only weight matrices and kernels (2-D and
    up) decay: biases, and the physical parameters a model learns (DeLaN's friction, 1-D), do not.
    """
    if not config.weight_decay:
        return torch.optim.Adam(module.parameters(), lr=config.lr)
    params = list(module.parameters())
    groups = [{"params": [p for p in params if p.ndim >= 2], "weight_decay": config.weight_decay},
              {"params": [p for p in params if p.ndim < 2], "weight_decay": 0.0}]
    return torch.optim.AdamW([g for g in groups if g["params"]], lr=config.lr)


def sensor_tare_seconds(preset: Preset, config: TrainConfig) -> float:
    """The contact-free start [s] on which the net's base-wrench input is tared (0: raw sensor)."""
    if "base_wrench" not in preset.inputs or preset.raw_sensor:
        return 0.0
    return float(config.tare_seconds)


def _is_recurrent(preset: Preset) -> bool:
    """Whether the net has an LSTM (front or residual branch): the nets whose gradients are clipped."""
    return clips_gradients(preset)  # declared with the kind (learn/kinds.py)


def _next_stop(config: TrainConfig, epoch: int, n_rounds: int, bad_epochs: int, lr_bad_epochs: int,
               lr: float) -> str | None:
    """Why training stops after round ``epoch`` of ``n_rounds`` (None: it goes on)."""
    last = epoch + 1 == n_rounds
    if config.budgeted:  # the schedule is the whole budget's; budget_patience only ends it early
        if last:
            return "budget"
        return "patience" if config.budget_patience is not None and bad_epochs >= config.budget_patience else None
    if bad_epochs >= config.patience:
        return "patience"
    if config.lr_schedule == "plateau" and lr <= config.min_lr and lr_bad_epochs >= config.lr_patience:
        return "lr-floor"  # the rate cannot be cut again, and it has plateaued at the floor
    return "epoch-cap" if last else None


def _rounds(config: TrainConfig, n: int):
    """The training plan: (number of rounds, steps per round, round -> [(batch sample indices, rate or None)]).

    Epoch recipes: a round is an epoch, its batches a permutation of the n training samples
    seeded by (seed, epoch), its rate the optimizer's own (None). Budgeted recipe: a round is
    ``budget_steps / budget_evals`` steps (rounds differ by one step at most); global step s takes
    batch s mod (batches per epoch) of epoch s div (batches per epoch), so batches walk the whole
    pool and the schedule's rate comes with each step.
    """
    per_epoch = -(-n // config.batch_size)

    def permutation(epoch):
        return np.random.default_rng([config.seed, epoch]).permutation(n)

    def batch(order, b):
        return np.sort(order[b * config.batch_size:(b + 1) * config.batch_size])

    if not config.budgeted:
        if config.max_batches_per_epoch:
            per_epoch = min(per_epoch, config.max_batches_per_epoch)

        def epoch_round(r):
            order = permutation(r)
            return [(batch(order, b), None) for b in range(per_epoch)]
        return config.max_epochs, per_epoch, epoch_round
    total, n_rounds = config.budget_steps, min(config.budget_evals, config.budget_steps)

    def budget_round(r):
        out, epoch, order = [], None, None
        for step in range(r * total // n_rounds, (r + 1) * total // n_rounds):
            e, b = divmod(step, per_epoch)
            if e != epoch:  # a round spans at most a few epochs: each permutation drawn once per round
                epoch, order = e, permutation(e)
            out.append((batch(order, b), budget_lr(config, step)))
        return out

    return n_rounds, -(-total // n_rounds), budget_round




def _state_copy(module) -> dict:
    """A detached copy of the module's weights and buffers: a candidate for the best epoch's."""
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


def _restore(module, opt, tensors: dict, info: dict, device) -> dict:
    """Weights, optimizer and torch's generators as a checkpoint left them; returns the best weights."""
    module.load_state_dict({k[6:]: v for k, v in tensors.items() if k.startswith("model.")})
    best_state = {k[5:]: v.to(device) for k, v in tensors.items() if k.startswith("best.")}
    _restore_optimizer(opt, {k: v for k, v in tensors.items() if k.startswith("opt.")}, info["optimizer"])
    if "rng.cpu" in tensors:  # checkpoints written before the generator state was saved lack it
        torch.set_rng_state(tensors["rng.cpu"])
    if "rng.cuda" in tensors and device.type == "cuda":
        torch.cuda.set_rng_state(tensors["rng.cuda"], device)
    return best_state


def _train_round(module, opt, ws_train, batches, clip, device, bar) -> list[float]:
    """One round's optimizer steps (an epoch, or a share of the budget); returns each step's loss."""
    losses = []
    for idx, step_lr in batches:
        if step_lr is not None:
            for group in opt.param_groups:
                group["lr"] = step_lr
        x, y, p = _batches(ws_train, idx, device)
        opt.zero_grad(set_to_none=True)
        loss = module.standardized_loss(module(x, p), y)
        loss.backward()
        if clip is not None:
            torch.nn.utils.clip_grad_norm_(module.parameters(), clip)
        opt.step()
        losses.append(float(loss.detach()))
        bar.update(1)
    return losses


def _fit(module, opt, preset, config, ds, ws_train, ws_val, out_dir, fingerprint, widths, prior, device, sensor_tare,
         cpu0: float):
    """The training loop; ``cpu0``: ``time.process_time()`` when this invocation's training work began."""
    n_rounds, steps_per_round, round_batches = _rounds(config, len(ws_train))
    history, bad_epochs, lr_bad_epochs, start_epoch, seconds, cpu_before = [], 0, 0, 0, 0.0, 0.0
    best_epoch, stopped_by = -1, None
    clip = config.grad_clip if _is_recurrent(preset) else None
    # The untrained model is the first candidate: a residual model starts as its physics
    # part (zero-initialized branch), and keeps it when training never beats it on validation.
    best_state = _state_copy(module)
    best_val = initial_val = evaluate_split(module, ws_val, device)
    resumed = _load_checkpoint(out_dir, fingerprint)
    if resumed is not None:
        info, tensors = resumed
        best_state = _restore(module, opt, tensors, info, device)
        history, best_val, bad_epochs = info["history"], info["best_val"], info["bad_epochs"]
        start_epoch, seconds = info["epoch"] + 1, info["train_seconds"]
        # The CPU of the invocations before this one; a checkpoint written before CPU time was recorded has none: not recorded.
        cpu_before = info.get("train_cpu_seconds", float("nan"))
        lr_bad_epochs, best_epoch, stopped_by = info["lr_bad_epochs"], info["best_epoch"], info["stopped_by"]
    stopped = stopped_by is not None
    bar = tqdm(total=n_rounds * steps_per_round, initial=start_epoch * steps_per_round, disable=not config.progress,
               desc=f"{preset.name}", unit="batch", dynamic_ncols=True)
    module.train()
    try:
        for epoch in range(start_epoch, n_rounds):
            if stopped:
                break
            t0 = time.perf_counter()
            losses = _train_round(module, opt, ws_train, round_batches(epoch), clip, device, bar)
            val = evaluate_split(module, ws_val, device)
            seconds += time.perf_counter() - t0
            lr = opt.param_groups[0]["lr"]  # the rate the round's last step trained with
            history.append({"epoch": epoch, "train_loss": float(np.mean(losses)), "val_loss": val, "lr": lr})
            if val < best_val - improvement_needed(config, best_val):
                best_val, bad_epochs, lr_bad_epochs, best_epoch = val, 0, 0, epoch
                best_state = _state_copy(module)
            else:
                bad_epochs += 1
                lr_bad_epochs += 1
            stopped_by = _next_stop(config, epoch, n_rounds, bad_epochs, lr_bad_epochs, lr)
            if stopped_by is None and config.lr_schedule == "plateau" and lr_bad_epochs >= config.lr_patience:
                for group in opt.param_groups:  # reduce on plateau, floored
                    group["lr"] = max(group["lr"] * config.lr_factor, config.min_lr)
                lr_bad_epochs = 0
            stopped = stopped_by is not None
            bar.set_description(f"{preset.name} {'round' if config.budgeted else 'epoch'} {epoch + 1}/{n_rounds}")
            bar.set_postfix(train=f"{history[-1]['train_loss']:.4f}", val=f"{val:.4f}", best=f"{best_val:.4f}")
            _save_checkpoint(out_dir, module, best_state, opt, {
                "fingerprint": fingerprint, "epoch": epoch, "history": history, "best_val": best_val,
                "bad_epochs": bad_epochs, "lr_bad_epochs": lr_bad_epochs, "best_epoch": best_epoch,
                "stopped_by": stopped_by, "train_seconds": seconds,
                "train_cpu_seconds": cpu_before + time.process_time() - cpu0})
    finally:
        bar.close()

    module.load_state_dict(best_state)
    module.eval()
    outcome = {"history": history, "stopped_by": stopped_by, "best_epoch": best_epoch, "val_loss": best_val,
               "initial_val_loss": initial_val, "train_samples": len(ws_train)}
    config_doc = _model_config(module, preset, config, ds, widths, prior, sensor_tare, fingerprint, outcome)
    module.cpu()
    save_model(module, config_doc, out_dir, train_seconds=seconds,
               train_cpu_seconds=cpu_before + time.process_time() - cpu0)
    for name in ("checkpoint.safetensors", "checkpoint.json"):
        (out_dir / name).unlink(missing_ok=True)
    return load_model(out_dir)


def qdd_provenance(ds) -> dict | None:
    """How the dataset's joint accelerations were made, for a stream that must make them alike:
    {"source": "filter", "cutoff_hz": f} (the generator's causal filter at the simulation rate),
    {"source": "exact", "cutoff_hz": None} (the simulator's own, or a synthetic set's analytic qdd),
    or None where the dataset does not say (an imported log)."""
    config = ds.meta.get("config") or {}
    if "qdd_cutoff_hz" in config:  # a generated set (qdd_source is recorded only when it is not the filter)
        source = config.get("qdd_source", "filter")
        return {"source": source, "cutoff_hz": float(config["qdd_cutoff_hz"]) if source == "filter" else None}
    if config.get("generator") == "synthetic":
        return {"source": "exact", "cutoff_hz": None}
    return None


def _model_config(module, preset, config, ds, widths, prior, sensor_tare, fingerprint, outcome: dict) -> dict:
    """The trained model's config.json: what it reads and predicts, its normalization, its data and training
    config, and how training went (``outcome``: history, stopped_by, best_epoch, val_loss, initial_val_loss,
    train_samples)."""
    history, stopped_by = outcome["history"], outcome["stopped_by"]
    return {
        "format": MODEL_FORMAT, "format_version": MODEL_FORMAT_VERSION,
        "preset": preset.to_dict(), "inputs": list(preset.inputs), "targets": list(preset.targets),
        "window": preset.window, "widths": widths, "robot": ds.meta["robot"],
        "analytic_params": config.analytic_params, "observer_gain": config.observer_gain,
        "record_hz": ds.meta.get("record_hz"), "qdd": qdd_provenance(ds),
        "prior": None if prior is None else prior.describe(),
        "sensor_tare_seconds": sensor_tare,
        "normalization": {k: getattr(module, k).cpu().double().tolist() for k in ("x_mean", "x_std", "y_mean", "y_std")},
        "dataset": {"path": str(ds.path), "checksum": ds.checksum, "scenario": ds.meta.get("scenario")},
        "train_config": asdict(config), "fingerprint": fingerprint, "history": history,
        "epochs": len(history), "stopped_by": stopped_by, "best_epoch": outcome["best_epoch"],
        "stopped_early": stopped_by in ("patience", "lr-floor"), "val_loss": outcome["val_loss"],
        "initial_val_loss": outcome["initial_val_loss"],
        "n_params": sum(p.numel() for p in module.parameters()),
        "train_samples": outcome["train_samples"], "torch": torch.__version__,
    }  # no wall-clock figures: they would make two identical runs' files differ (timing.json has them)
