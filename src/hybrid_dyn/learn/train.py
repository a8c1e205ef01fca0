"""Training: the seed's recipe (Adam, MSE, early stopping), deterministic and resumable.

Recipe (seed 3.2): Glorot-uniform initialization, Adam at lr 1e-3, MSE loss on
standardized targets, training until the validation loss has not improved for
5 consecutive epochs. The weights of the best validation epoch are kept (as
Keras' ``restore_best_weights``; the seed does not say, and the best epoch is
what early stopping is for); the untrained model counts as epoch "0", so a
residual model that never beats its physics part on validation stays it. Choices the seed leaves open: batch size 256, at
most 200 epochs (see ``docs/models.md``).

Determinism: the initial weights come from ``torch.manual_seed(seed)``, the
shuffling of epoch e from a generator seeded with (seed, e), and PyTorch runs
with deterministic algorithms; a run resumed from its checkpoint continues
exactly as if it had never stopped.

Checkpoints (every epoch, atomically): ``checkpoint.safetensors`` (weights,
best weights, Adam state) and ``checkpoint.json`` (epoch, history, counters,
fingerprint). The fingerprint (preset + training config + dataset checksum)
decides whether an existing checkpoint or model in ``out_dir`` is this run's.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from safetensors import safe_open
from safetensors.torch import save_file
from tqdm.auto import tqdm

from ..analytic.tare import TARE_SECONDS
from ..data import Dataset, load_dataset
from ..data.windows import WindowedSplit, concat_fields
from .model import (MODEL_FORMAT, MODEL_FORMAT_VERSION, HybridModel, ModelError, TrainedModel, canonical_json,
                    check_instances, load_model, save_model)
from .presets import Preset, get_preset
from .priors import AnalyticPrior

STD_FLOOR = 1e-6  # a (nearly) constant column is scaled by 1, not blown up


@dataclass
class TrainConfig:
    """How to train. Defaults follow the seed where it speaks (lr, patience).

    seed: weights and shuffling. batch_size: samples per Adam step.
    max_epochs: upper bound; early stopping usually ends sooner.
    patience: epochs without validation improvement before stopping (seed: 5).
    max_batches_per_epoch: cap an epoch's batches (quick runs, tuning); None = all.
    analytic_params: parameter set of the residual models' analytic part
    (None: the robot's nominal URDF; a set name or a JSON path, e.g. identified).
    observer_gain: momentum-observer bandwidth K [1/s] for the momentum prior.
    tare_seconds: base-wrench priors: each instance's contact-free start used to
    tare the base sensor [s] (``analytic/tare.py``); 0 = no tare.
    device: "auto" (CUDA when present, else CPU), "cpu" or "cuda".
    num_threads: CPU threads for PyTorch during training (None: PyTorch's default).
    Small batches on a shared machine often run faster on one thread.
    """

    seed: int = 0
    batch_size: int = 256
    max_epochs: int = 200
    patience: int = 5
    min_delta: float = 0.0
    lr: float = 1e-3
    max_batches_per_epoch: int | None = None
    analytic_params: str | None = None
    observer_gain: float = 20.0
    tare_seconds: float = TARE_SECONDS
    device: str = "auto"
    progress: bool = True
    num_threads: int | None = None

    def fingerprint_fields(self) -> dict:
        d = asdict(self)
        for k in ("device", "progress", "num_threads"):  # where and how loudly a run goes does not change its result
            d.pop(k)
        return d


def _device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


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


def field_widths(instance, names) -> dict:
    return {n: int(np.asarray(instance[n]).reshape(len(instance), -1).shape[1]) for n in names}


def _stats(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = a.astype(np.float64)
    mean, std = a.mean(0), a.std(0)
    return mean, np.where(std < STD_FLOOR, 1.0, std)


# ------------------------------------------------------------- checkpoints
def _optimizer_tensors(opt: torch.optim.Optimizer) -> tuple[dict, dict]:
    sd = opt.state_dict()
    tensors = {}
    for pid, st in sd["state"].items():
        for k, v in st.items():
            tensors[f"opt.{pid}.{k}"] = torch.as_tensor(v).detach().cpu().contiguous()
    return tensors, {"param_groups": sd["param_groups"]}


def _restore_optimizer(opt: torch.optim.Optimizer, tensors: dict, meta: dict) -> None:
    state: dict = {}
    for key, v in tensors.items():
        _, pid, k = key.split(".", 2)
        state.setdefault(int(pid), {})[k] = v
    opt.load_state_dict({"state": state, "param_groups": meta["param_groups"]})


def _save_checkpoint(out_dir: Path, module, best_state, opt, info: dict) -> None:
    tensors = {f"model.{k}": v.detach().cpu().contiguous() for k, v in module.state_dict().items()}
    tensors.update({f"best.{k}": v.detach().cpu().contiguous() for k, v in best_state.items()})
    opt_tensors, opt_meta = _optimizer_tensors(opt)
    tensors.update(opt_tensors)
    info = dict(info, optimizer=opt_meta)
    tmp = out_dir / "checkpoint.safetensors.partial"
    save_file(tensors, str(tmp), metadata={"fingerprint": info["fingerprint"], "epoch": str(info["epoch"])})
    jtmp = out_dir / "checkpoint.json.partial"
    jtmp.write_text(json.dumps(info, indent=1))
    os.replace(tmp, out_dir / "checkpoint.safetensors")
    os.replace(jtmp, out_dir / "checkpoint.json")


def _load_checkpoint(out_dir: Path, fingerprint: str):
    jpath, tpath = out_dir / "checkpoint.json", out_dir / "checkpoint.safetensors"
    if not jpath.is_file() or not tpath.is_file():
        return None
    try:
        info = json.loads(jpath.read_text())
        with safe_open(str(tpath), framework="pt") as f:
            meta = f.metadata() or {}
            tensors = {k: f.get_tensor(k) for k in f.keys()}
    except Exception:  # a checkpoint torn by a kill is discarded: the run restarts cleanly
        return None
    if info.get("fingerprint") != fingerprint:
        raise ModelError(f"{out_dir} holds a checkpoint of another run (other preset, config or data); "
                         "choose another --out or delete it")
    if meta.get("fingerprint") != fingerprint or meta.get("epoch") != str(info["epoch"]):
        return None  # the two files are from different epochs (killed between the renames)
    return info, tensors


# ------------------------------------------------------------------ training
def run_fingerprint(preset: Preset, config: TrainConfig, dataset_checksum: str) -> str:
    return hashlib.sha256(canonical_json({"preset": preset.to_dict(), "train": config.fingerprint_fields(),
                                          "dataset": dataset_checksum}).encode()).hexdigest()


def train_model(dataset, preset, out_dir, config: TrainConfig | None = None) -> TrainedModel:
    """Train ``preset`` (a name or a :class:`Preset`) on ``dataset`` (a Dataset or its path).

    Writes the model to ``out_dir``. A finished model of the same run there is
    returned as is; a checkpoint of the same run is resumed; anything of another
    run there is an error (nothing is overwritten).
    """
    config = config or TrainConfig()
    preset = get_preset(preset)
    ds: Dataset = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
    out_dir = Path(out_dir)
    fingerprint = run_fingerprint(preset, config, ds.checksum)
    if (out_dir / "config.json").is_file():
        model = load_model(out_dir)
        if model.config.get("fingerprint") != fingerprint:
            raise ModelError(f"{out_dir} holds a finished model of another run (other preset, config or data); "
                             "choose another --out or delete it")
        return model
    out_dir.mkdir(parents=True, exist_ok=True)

    robot_name = ds.meta.get("robot")
    if not robot_name:
        raise ModelError(f"dataset {ds.path} does not name its robot")
    train, val = ds.split("train"), ds.split("val")
    if not train or not val:
        raise ModelError(f"dataset {ds.path} needs instances in its train and val splits")
    missing = sorted((set(preset.inputs) | set(preset.targets)) - set(ds.fields))
    if missing:
        raise ModelError(f"dataset {ds.path} lacks fields {missing} that preset {preset.name!r} needs")

    prior = None
    if preset.prior is not None:
        from ..analytic.robot import load_robot

        prior = AnalyticPrior(preset.prior, load_robot(robot_name, params=config.analytic_params),
                              ds.meta.get("record_hz"), config.observer_gain, config.tare_seconds)
    widths = field_widths(train[0], list(dict.fromkeys(preset.inputs + preset.targets)))
    needed = set(preset.inputs) | set(preset.targets) | (set(prior.fields) if prior else set())
    check_instances(train + val, needed, widths, f"preset {preset.name!r}")

    def split_data(instances):
        extra = None
        if prior is not None:
            extra = {"prior": prior.compute_instances(instances, out_dir / "analytic_cache", ds.checksum)}
        return WindowedSplit(instances, preset.window, list(preset.inputs), list(preset.targets), extra=extra)

    ws_train, ws_val = split_data(train), split_data(val)
    x_mean, x_std = _stats(concat_fields(train, list(preset.inputs)))
    y_mean, y_std = _stats(ws_train.y)

    device = _device(config.device)
    with _deterministic(config.num_threads):
        torch.manual_seed(config.seed)
        module = HybridModel(preset, widths)
        module.set_normalization(x_mean, x_std, y_mean, y_std)
        module.to(device)
        opt = torch.optim.Adam(module.parameters(), lr=config.lr)
        return _fit(module, opt, preset, config, ds, ws_train, ws_val, out_dir, fingerprint, widths, prior, device)


def _batches(ws: WindowedSplit, idx: np.ndarray, device):
    x, y = ws[idx]
    p = ws.extra["prior"][idx] if "prior" in ws.extra else None
    to = lambda a: torch.from_numpy(np.ascontiguousarray(a)).to(device)  # noqa: E731
    return to(x), to(y), (None if p is None else to(p))


def evaluate_split(module: HybridModel, ws: WindowedSplit, device, batch_size: int = 4096) -> float:
    """Standardized MSE over a whole split (every sample weighs the same)."""
    module.eval()
    total, n = 0.0, 0
    with torch.no_grad():
        for s in range(0, len(ws), batch_size):
            idx = np.arange(s, min(s + batch_size, len(ws)))
            x, y, p = _batches(ws, idx, device)
            total += float(module.standardized_loss(module(x, p), y)) * len(idx)
            n += len(idx)
    module.train()
    return total / max(n, 1)


def _fit(module, opt, preset, config, ds, ws_train, ws_val, out_dir, fingerprint, widths, prior, device):
    n = len(ws_train)
    n_batches = -(-n // config.batch_size)
    if config.max_batches_per_epoch:
        n_batches = min(n_batches, config.max_batches_per_epoch)
    history, bad_epochs, start_epoch, seconds = [], 0, 0, 0.0
    # The untrained model is the first candidate: a residual model starts as its physics
    # part (zero-initialized branch), and keeps it when training never beats it on validation.
    best_state = {k: v.detach().clone() for k, v in module.state_dict().items()}
    best_val = initial_val = evaluate_split(module, ws_val, device)
    resumed = _load_checkpoint(out_dir, fingerprint)
    if resumed is not None:
        info, tensors = resumed
        module.load_state_dict({k[6:]: v for k, v in tensors.items() if k.startswith("model.")})
        best_state = {k[5:]: v.to(device) for k, v in tensors.items() if k.startswith("best.")}
        _restore_optimizer(opt, {k: v for k, v in tensors.items() if k.startswith("opt.")}, info["optimizer"])
        history, best_val, bad_epochs = info["history"], info["best_val"], info["bad_epochs"]
        start_epoch, seconds = info["epoch"] + 1, info["train_seconds"]
    stopped = bad_epochs >= config.patience
    bar = tqdm(total=config.max_epochs * n_batches, initial=start_epoch * n_batches, disable=not config.progress,
               desc=f"{preset.name}", unit="batch", dynamic_ncols=True)
    module.train()
    epoch = start_epoch
    try:
        for epoch in range(start_epoch, config.max_epochs):
            if stopped:
                break
            t0 = time.perf_counter()
            order = np.random.default_rng([config.seed, epoch]).permutation(n)
            losses = []
            for b in range(n_batches):
                x, y, p = _batches(ws_train, np.sort(order[b * config.batch_size:(b + 1) * config.batch_size]), device)
                opt.zero_grad(set_to_none=True)
                loss = module.standardized_loss(module(x, p), y)
                loss.backward()
                opt.step()
                losses.append(float(loss.detach()))
                bar.update(1)
            val = evaluate_split(module, ws_val, device)
            seconds += time.perf_counter() - t0
            history.append({"epoch": epoch, "train_loss": float(np.mean(losses)), "val_loss": val})
            if val < best_val - config.min_delta:
                best_val, bad_epochs = val, 0
                best_state = {k: v.detach().clone() for k, v in module.state_dict().items()}
            else:
                bad_epochs += 1
            stopped = bad_epochs >= config.patience
            bar.set_description(f"{preset.name} epoch {epoch + 1}/{config.max_epochs}")
            bar.set_postfix(train=f"{history[-1]['train_loss']:.4f}", val=f"{val:.4f}", best=f"{best_val:.4f}")
            _save_checkpoint(out_dir, module, best_state, opt, {
                "fingerprint": fingerprint, "epoch": epoch, "history": history, "best_val": best_val,
                "bad_epochs": bad_epochs, "train_seconds": seconds})
    finally:
        bar.close()

    module.load_state_dict(best_state)
    module.eval()
    config_doc = {
        "format": MODEL_FORMAT, "format_version": MODEL_FORMAT_VERSION,
        "preset": preset.to_dict(), "inputs": list(preset.inputs), "targets": list(preset.targets),
        "window": preset.window, "widths": widths, "robot": ds.meta["robot"],
        "analytic_params": config.analytic_params, "observer_gain": config.observer_gain,
        "record_hz": ds.meta.get("record_hz"), "prior": None if prior is None else prior.describe(),
        "normalization": {k: getattr(module, k).cpu().double().tolist() for k in ("x_mean", "x_std", "y_mean", "y_std")},
        "dataset": {"path": str(ds.path), "checksum": ds.checksum, "scenario": ds.meta.get("scenario")},
        "train_config": asdict(config), "fingerprint": fingerprint, "history": history,
        "epochs": len(history), "stopped_early": bool(stopped), "val_loss": best_val, "initial_val_loss": initial_val,
        "train_seconds": seconds, "n_params": sum(p.numel() for p in module.parameters()),
        "train_samples": len(ws_train), "torch": torch.__version__,
    }
    module.cpu()
    save_model(module, config_doc, out_dir)
    for name in ("checkpoint.safetensors", "checkpoint.json"):
        (out_dir / name).unlink(missing_ok=True)
    return load_model(out_dir)
