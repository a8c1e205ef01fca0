"""A trained model: the network, its standardization, its analytic part, its files.

The design in full: ``docs/design/learn.md`` (trained_model.py).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import torch
from safetensors.torch import save_file
from torch import nn

from ..data.input_windows import concat_fields, window_index
from .kinds import NETWORK_KINDS, build_parts
from .model_file import (METADATA_KEY, TIMING_FORMAT, ModelError, ModelFiles, SavedModel, canonical_json,  # noqa: F401
                         config_digest, partial, read_file_metadata, read_model_config, read_timing,
                         recorded_train_cpu, tensors_digest, timing_doc)  # (re-exported: imported from here before)
from .presets import Preset
from ..analytic.tare import tared_runs
from .priors import AnalyticPrior

MODEL_FORMAT = "hybrid_dyn.model"
# 2: tensor digest in the metadata, wall-clock figures in timing.json; 3: the analytic prior by its
# canonical estimator name (a file of 1-2 spells it the old way: read as the estimator's alias, with a warning).
MODEL_FORMAT_VERSION = 3
# What training writes into a model folder besides the model's files: checkpoints (``checkpoints.py``).
_OWN_TEMPORARY = re.compile(r"(model\.safetensors|config\.json|timing\.json|checkpoint\.safetensors|checkpoint\.json)"
                            r"\.partial")
MODEL_FILES = ModelFiles(MODEL_FORMAT, MODEL_FORMAT_VERSION, "model", framework="pt", save_tensors=save_file,
                         digest=tensors_digest, temporary=partial, own_temporary=_OWN_TEMPORARY, saved_with="weights",
                         redo="retrain", run_differs="preset, config or data", choose="--out")


def file_metadata(config: dict, tensors: dict) -> dict:
    """The safetensors metadata of a model file (``ModelFiles.metadata``): one key holding canonical JSON."""
    return MODEL_FILES.metadata(config, tensors)


def check_instances(instances, fields, widths: dict, who: str) -> None:
    """Every instance has the fields, with the expected widths, and only finite values."""
    for inst in instances:
        missing = sorted(set(fields) - set(inst.fields))
        if missing:
            raise ModelError(f"instance {inst.name} lacks fields {missing} that {who} needs")
        for f in sorted(fields):
            a = np.asarray(inst[f]).reshape(len(inst), -1)
            if f in widths and a.shape[1] != widths[f]:
                raise ModelError(f"instance {inst.name}: field {f} has {a.shape[1]} columns, {who} expects "
                                 f"{widths[f]} (another robot?)")
            if not np.isfinite(a).all():
                row = int(np.argwhere(~np.isfinite(a))[0][0])
                raise ModelError(f"instance {inst.name}: field {f} holds NaN or inf (first at sample {row})")


class HybridModel(nn.Module):
    """The torch module of any preset: standardization, network(s), DeLaN, prior sum.

    widths: field name -> columns (q: nv, base_wrench: 6, tip_force: 3, ...).
    """

    def __init__(self, preset: Preset, widths: dict):
        super().__init__()
        self.preset = preset
        self.widths = dict(widths)
        n_in = sum(widths[f] for f in preset.inputs)
        n_out = sum(widths[f] for f in preset.targets)
        self.n_in, self.n_out = n_in, n_out
        for name, n in (("x_mean", n_in), ("x_std", n_in), ("y_mean", n_out), ("y_std", n_out)):
            self.register_buffer(name, torch.zeros(n) if "mean" in name else torch.ones(n))
        self.delan = self.friction = self.net = None
        for name, module in build_parts(preset, n_in, n_out, widths).items():  # the kind's modules (kinds.py),
            setattr(self, name, module)  # in its declared order: the order of the state dict
        if self.net is not None and (preset.prior is not None or self.delan is not None):
            # A residual branch starts at exactly zero: the hybrid model begins as its
            # physics part and moves away only where the data say so (hidden layers
            # keep the reference study's Glorot init, so the gradients are not degenerate).
            out_layer = self.net.head[-1]
            nn.init.zeros_(out_layer.weight)
            nn.init.zeros_(out_layer.bias)

    def set_normalization(self, x_mean, x_std, y_mean, y_std) -> None:
        for name, v in (("x_mean", x_mean), ("x_std", x_std), ("y_mean", y_mean), ("y_std", y_std)):
            getattr(self, name).copy_(torch.as_tensor(np.asarray(v), dtype=torch.float32))
        if self.delan is not None:
            nv = self.widths["q"]
            self.delan.q_mean.copy_(self.x_mean[:nv])
            self.delan.q_std.copy_(self.x_std[:nv])
            self.delan.torque_scale.fill_(float(self.y_std.mean()))

    def forward(self, x: torch.Tensor, prior: torch.Tensor | None = None) -> torch.Tensor:
        """x: raw window (B, L, n_in); prior: (B, n_out) for residual presets. Returns y (B, n_out)."""
        xs = (x - self.x_mean) / self.x_std
        if self.delan is not None:
            nv = self.widths["q"]
            last = x[:, -1]
            q, qd, qdd = last[:, :nv], last[:, nv:2 * nv], last[:, 2 * nv:3 * nv]
            y = self.delan(q, qd, qdd)
            if self.friction is not None:
                y = y + self.friction(qd)
            if self.net is not None:
                y = y + self.y_std * self.net(xs)
            return y
        if self.preset.prior is not None:
            if prior is None:
                raise ValueError(f"preset {self.preset.name!r} needs its analytic prior")
            return prior + self.y_std * self.net(xs)
        return self.y_mean + self.y_std * self.net(xs)

    def standardized_loss(self, y_pred: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """MSE on standardized targets (the reference study's loss; comparable across presets)."""
        return torch.mean(((y_pred - y) / self.y_std) ** 2)


class TrainedModel(SavedModel):
    """A trained model with the uniform API the bench harness and the streaming estimator use.

    ``predict(instances)``: one (T, n_out) array per instance, physical units, every
    sample (sequence models edge-padded, see ``hybrid_dyn.data.input_windows``).
    ``predict_window(x, prior=None)``: one raw window (L, n_in) -> (n_out,).
    ``config``: the dict stored in config.json. ``n_params``, ``train_seconds``,
    ``history`` (per-epoch train/val loss), ``val_loss`` (standardized MSE): see :class:`SavedModel`.
    """

    FILES = MODEL_FILES

    def __init__(self, module: HybridModel, config: dict, path: Path | None = None,
                 train_seconds: float | None = None):
        super().__init__(config, path, train_seconds)
        self.module = module.eval()
        self.preset = Preset.from_dict(config["preset"])
        self._robot = None
        self._prior = None
        self._fast = None

    # ---------------------------------------------------------------- facts
    @property
    def n_params(self) -> int:
        return sum(p.numel() for p in self.module.parameters())

    @property
    def inputs(self) -> list:
        return list(self.preset.inputs)

    @property
    def targets(self) -> list:
        return list(self.preset.targets)

    @property
    def window(self) -> int:
        return self.preset.window

    @property
    def robot(self):
        if self._robot is None:
            from ..analytic.robot import load_robot

            self._robot = load_robot(self.config["robot"], params=self.config.get("analytic_params"))
        return self._robot

    @property
    def prior(self) -> AnalyticPrior | None:
        if self.preset.prior is None:
            return None
        if self._prior is None:
            described = self.config.get("prior") or {}
            # The friction as trained, from the config (models saved before it had none); the
            # inertials from the parameter file, which must be the one trained on.
            prior = AnalyticPrior(self.preset.prior, self.robot, self.config.get("record_hz"),
                                  self.config.get("observer_gain", 20.0),
                                  described.get("tare_seconds", 0.0),  # models saved before the tare had none
                                  friction=described.get("friction"))
            if described.get("params_sha256") and prior.params_sha256 != described["params_sha256"]:
                raise ModelError(f"model {self.path}: its analytic part was trained on the parameter file "
                                 f"{self.config.get('analytic_params')} with sha256 {described['params_sha256'][:12]}..., "
                                 f"and that file now has {str(prior.params_sha256)[:12]}...: restore it or retrain")
            self._prior = prior
        return self._prior

    @property
    def sensor_tare_seconds(self) -> float:
        """The contact-free start [s] of each run on which the net's base-wrench input is tared
        (0: the raw sensor; models saved before that option read it raw)."""
        return float(self.config.get("sensor_tare_seconds", 0.0))

    def sensor_view(self, instances) -> list:
        """The instances as the net's inputs see them: the base sensor tared as in training."""
        if self.sensor_tare_seconds == 0:  # nothing to tare: no robot needed (an arm known for data only has none)
            return list(instances)
        return tared_runs(instances, self.robot, self.config.get("record_hz"), self.sensor_tare_seconds)

    # ----------------------------------------------------------- prediction
    def _check_instances(self, instances) -> None:
        check_instances(instances, set(self.inputs) | (set(self.prior.fields) if self.prior else set()),
                        self.config["widths"], f"model {self.preset.name!r}")

    def predict(self, instances, batch_size: int = 4096, priors: list | None = None) -> list[np.ndarray]:
        """Predictions [physical units] (T, n_out) float64 for each instance, every sample.

        priors: the analytic part per instance when already computed (else computed here).
        """
        instances = list(instances)
        self._check_instances(instances)
        if not instances:
            return []
        x_all = concat_fields(self.sensor_view(instances), self.inputs)
        lengths = [len(i) for i in instances]
        index = window_index(lengths, self.window)
        prior_all = None
        if self.prior is not None:
            if priors is None:
                priors = self.prior.compute_instances(instances)
            prior_all = np.concatenate([np.asarray(p, np.float32).reshape(len(p), -1) for p in priors])
        device = next(self.module.buffers()).device
        out = np.empty((len(index), self.module.n_out))
        with torch.no_grad():  # not inference_mode: DeLaN differentiates inside its forward
            for s in range(0, len(index), batch_size):
                x = torch.from_numpy(x_all[index[s:s + batch_size]]).to(device)
                p = None if prior_all is None else torch.from_numpy(prior_all[s:s + batch_size]).to(device)
                out[s:s + batch_size] = self.module(x, p).double().cpu().numpy()
        return np.split(out, np.cumsum(lengths)[:-1])

    def evaluate(self, instances, **kw) -> dict:
        """Losses and errors on instances: standardized MSE (the reference study's loss) and RMSE [physical units]."""
        instances = list(instances)
        pred = np.concatenate(self.predict(instances, **kw))
        y = concat_fields(instances, self.targets).astype(np.float64)
        err = pred - y
        y_std = self.module.y_std.double().cpu().numpy()
        return {"loss": float(np.mean((err / y_std) ** 2)), "rmse": float(np.sqrt(np.mean(err ** 2))),
                "rmse_per_component": np.sqrt(np.mean(err ** 2, axis=0)).tolist(),
                "max_abs_error": float(np.abs(err).max()), "n_samples": len(y)}

    def predict_window(self, x, prior=None) -> np.ndarray:
        """One prediction [physical units] (n_out,) from one raw window x (L, n_in).

        x holds the model's input fields side by side (``model.inputs``, widths in
        ``model.config["widths"]``), oldest sample first, in physical units; pad
        the start of a run with its first sample, as training did. A model with
        ``sensor_tare_seconds > 0`` expects the base wrench tared (``StreamingTare``).
        prior: the analytic part (n_out,) at the window's last sample. Optional for
        the per-sample priors (computed here from the last row, which holds every
        field they need); required for ``momentum`` (a filter with state: pass
        ``MomentumObserver.step_force(q, qd, tau_J)``) and for a tared base-wrench
        prior (its offset comes from the run's start: ``prior.single`` on the tared wrench).
        Runs through :mod:`fastpath` (numba kernels; DeLaN with hand-derived derivatives).
        """
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (self.window, self.module.n_in):
            raise ModelError(f"window must have shape ({self.window}, {self.module.n_in}) for {self.inputs}, got {x.shape}")
        if not np.isfinite(x).all():
            raise ModelError("window holds NaN or inf")
        if self.preset.prior is not None and prior is None:
            if self.prior.tare_seconds > 0:
                raise ModelError(f"model {self.preset.name!r} tares the base sensor on each run's first "
                                 f"{self.prior.tare_seconds} s: pass `prior`, computed on the tared wrench")
            prior = self.prior.single(self._split_row(x[-1]))
        if self._fast is None:
            from .fastpath import FastNet

            m, kind = self.module, NETWORK_KINDS.lookup(self.preset.kind)
            # A net kind's net through FastNet; a structured kind (DeLaN) through its own declared fast path.
            structured = None if kind.is_net else kind.fast({p: getattr(m, p) for p in kind.parts})
            self._fast = (None if m.net is None else FastNet(m.net), m.x_mean.double().numpy(), m.x_std.double().numpy(),
                          m.y_mean.double().numpy(), m.y_std.double().numpy(), structured)
        net, x_mean, x_std, y_mean, y_std, delan = self._fast
        if delan is not None:
            nv = self.config["widths"]["q"]
            y = delan(x[-1, :nv], x[-1, nv:2 * nv], x[-1, 2 * nv:3 * nv])
            return y if net is None else y + y_std * net((x - x_mean) / x_std)
        y = y_std * net((x - x_mean) / x_std)
        return y + (np.asarray(prior, float) if self.preset.prior is not None else y_mean)

    def _split_row(self, row: np.ndarray) -> dict:
        out, i = {}, 0
        for f in self.inputs:
            w = self.config["widths"][f]
            out[f] = row[i:i + w]
            i += w
        return out

    # ------------------------------------------------------------------ I/O
    def save(self, model_dir) -> None:
        seconds = self.train_seconds
        save_model(self.module, self.config, model_dir, None if np.isnan(seconds) else seconds)


def save_model(module: HybridModel, config: dict, model_dir, train_seconds: float | None = None,
               train_cpu_seconds: float | None = None) -> None:
    """Write model.safetensors (config and tensor digests in its metadata), timing.json
    (train_seconds, when given, and train_cpu_seconds, the CPU time training took [s], when known)
    and config.json, each atomically (``ModelFiles.write``).

    Only what the digests cover is reproducible, so wall-clock figures stay out of
    config.json and the metadata: two identical runs write byte-identical files.
    """
    tensors = {k: v.detach().cpu().contiguous() for k, v in module.state_dict().items()}
    MODEL_FILES.write(model_dir, tensors, config, train_seconds, train_cpu_seconds)


def load_model(model_dir, robot=None, device: str = "cpu") -> TrainedModel:
    """Open a model directory. robot: a Robot or robot name the model must be for (optional).

    Refuses: a missing or partial directory, a config.json that is not the one
    written with the weights, tensors whose bytes do not match their digest (a
    flipped bit), a file older than the tensor digest (format 1: retrain it), a
    model with an analytic part for a robot without a description, another robot.
    A data-only model (no analytic part) loads whatever its robot's name.
    """
    model_dir = Path(model_dir)
    cpath, wpath = model_dir / "config.json", model_dir / "model.safetensors"
    config = MODEL_FILES.read_config(model_dir)
    meta, tensors = MODEL_FILES.read_tensors(model_dir)
    MODEL_FILES.check_config_digest(model_dir, config, meta)
    if config.get("format") != MODEL_FORMAT or config.get("format_version", 0) > MODEL_FORMAT_VERSION:
        raise ModelError(f"{cpath}: not a {MODEL_FORMAT} v<={MODEL_FORMAT_VERSION} model")
    if "tensors_sha256" not in meta:
        raise ModelError(f"{wpath} predates the tensor digest (model format {MODEL_FORMAT_VERSION}): its weights "
                         f"cannot be checked for corruption; retrain it (delete {model_dir}, rerun train)")
    MODEL_FILES.check_tensors_digest(model_dir, meta, tensors)
    train_seconds = MODEL_FILES.train_seconds(model_dir, config)  # timing.json names the config as saved

    from ..description import ROBOTS, has_description

    # The analytic part, and the base sensor's tare, need the robot's model.
    if Preset.from_dict(config["preset"]).prior is not None or config.get("sensor_tare_seconds", 0) > 0:
        if not has_description(config["robot"]):
            raise ModelError(f"model {model_dir} needs a description of robot {config['robot']!r} for its analytic "
                             f"part or its sensor tare, and this toolkit has none "
                             f"(available: {', '.join(ROBOTS.names(data_only=False))})")
    if robot is not None:
        name = robot if isinstance(robot, str) else robot.name
        if name != config["robot"]:
            raise ModelError(f"model {model_dir} was trained for robot {config['robot']!r}, not {name!r}")
    preset = Preset.from_dict(config["preset"])
    module = HybridModel(preset, config["widths"])
    try:
        module.load_state_dict(tensors, strict=True)
    except RuntimeError as err:
        raise ModelError(f"{wpath} does not fit the architecture in config.json: {err}") from err
    module.to(device)
    # The analytic part always uses the model's own robot and parameter set (config), never a
    # caller's Robot that may carry other parameters, a payload or a mis-mounted sensor.
    return TrainedModel(module, config, path=model_dir, train_seconds=train_seconds)
