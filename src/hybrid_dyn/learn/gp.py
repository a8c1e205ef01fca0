"""Gaussian-process regression of the joint torques: the first model family that is not PyTorch.

The design in full: ``docs/design/learn.md`` (gp.py).
"""
from __future__ import annotations

import hashlib
import re
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np
import torch
from safetensors.numpy import save_file
from scipy.spatial.distance import cdist

from ..data.dataset import Dataset, load_dataset
from ..errors import UsageError
from ..outputs import output_lock, unique_temp
from .model_file import ModelError, ModelFiles, SavedModel, canonical_json, tensors_digest
from .trained_model import check_instances

GP_FORMAT = "hybrid_dyn.gp"
GP_FORMAT_VERSION = 1
TENSORS = ("x_mean", "x_std", "z_train", "alpha", "constant", "length_scale", "noise_level", "y_mean", "y_std")
STD_EPS = 1e-9  # added to each input's standard deviation: a constant input must not divide by zero
PREDICT_CHUNK = 1024  # samples per kernel block: 1024 x rows x 8 bytes (64 MB at 8000 rows)


def _digest(tensors: dict) -> str:
    """The tensor digest of the PyTorch models (``model_file.tensors_digest``: name, dtype, shape, bytes),
    on numpy arrays."""
    return tensors_digest({k: torch.from_numpy(np.ascontiguousarray(v)) for k, v in tensors.items()})


# A GP's files: those of every model family (``model_file.py``), its tensors numpy arrays, written through
# per-run temporaries (``outputs.unique_temp``).
_OWN_TEMPORARY = re.compile(r"(model\.safetensors|config\.json|timing\.json)\.partial\.\d+\.[0-9a-f]{8}")
GP_FILES = ModelFiles(GP_FORMAT, GP_FORMAT_VERSION, "GP model", framework="np", save_tensors=save_file,
                      digest=_digest, temporary=unique_temp, own_temporary=_OWN_TEMPORARY, saved_with="tensors",
                      redo="refit", run_differs="config or data", choose="output folder")


@dataclass
class GPConfig:
    """How a GP model is fitted (defaults: the real-log baselines', ``reports/studies/interpolation-control``).

    hyper_rows: training rows the hyperparameters are fitted on (O(n^3) per L-BFGS step).
    rows: training rows the GP is conditioned on, at most (memory 8 rows^2 bytes).
    seed: picks both row subsets; the same seed, data and config give the same model.
    inputs, target: dataset fields (target: per-joint torques, Nm).
    """

    hyper_rows: int = 600
    rows: int = 8000
    seed: int = 0
    inputs: tuple = ("q", "qd", "qdd")
    target: str = "tau_m"
    constant_bounds: tuple = (1e-2, 1e2)
    length_scale_bounds: tuple = (1e-2, 1e3)  # standardized inputs: 1e3 switches an input off
    noise_bounds: tuple = (1e-6, 1.0)
    noise_init: float = 1e-2

    def __post_init__(self):
        self.inputs = tuple(self.inputs)
        for name in ("constant_bounds", "length_scale_bounds", "noise_bounds"):
            setattr(self, name, tuple(float(b) for b in getattr(self, name)))
        self.validate()

    def validate(self) -> None:
        problems = [f"{k} must be an integer >= 1, got {getattr(self, k)!r}" for k in ("hyper_rows", "rows")
                    if not (isinstance(getattr(self, k), int) and getattr(self, k) >= 1)]
        if not self.inputs:
            problems.append("inputs must name at least one field")
        for name in ("constant_bounds", "length_scale_bounds", "noise_bounds"):
            lo, hi = getattr(self, name)
            if not 0 < lo < hi:
                problems.append(f"{name} must be (low, high) with 0 < low < high, got {(lo, hi)}")
        if not self.noise_bounds[0] <= self.noise_init <= self.noise_bounds[1]:
            problems.append(f"noise_init {self.noise_init} must lie in noise_bounds {self.noise_bounds}")
        if problems:
            raise UsageError("invalid GPConfig: " + "; ".join(problems))

    def to_dict(self) -> dict:
        d = asdict(self)
        return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}

    @classmethod
    def from_dict(cls, d: dict) -> "GPConfig":
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ModelError(f"unknown GPConfig keys {unknown}; known: {sorted(known)}")
        return cls(**d)


# --------------------------------------------------------------------------- fitting (arrays)

@dataclass
class GPHyperparameters:
    """Fitted kernel hyperparameters, one entry per output column (joint), on standardized inputs."""

    constant: np.ndarray      # (nv,) signal variance c
    length_scale: np.ndarray  # (nv, d) ARD length scales l
    noise_level: np.ndarray   # (nv,) white-noise variance s
    log_marginal_likelihood: list


def _rows(n_total: int, n: int, seed) -> np.ndarray:
    """At most ``n`` of ``n_total`` row indices, chosen at random by ``seed``, in their original order."""
    return np.sort(np.random.default_rng(seed).permutation(n_total)[:n])


def _standardization(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return x.mean(0), x.std(0) + STD_EPS


def _sklearn_kernel(config: GPConfig, d: int, constant=1.0, length_scale=None, noise_level=None):
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    ls = np.ones(d) if length_scale is None else np.asarray(length_scale, np.float64)
    return (ConstantKernel(float(constant), config.constant_bounds) * RBF(ls, config.length_scale_bounds)
            + WhiteKernel(config.noise_init if noise_level is None else float(noise_level), config.noise_bounds))


def fit_gp_hyperparameters(x: np.ndarray, y: np.ndarray, config: GPConfig | None = None) -> GPHyperparameters:
    """Per column of ``y`` (N, nv), the kernel's hyperparameters by maximum marginal likelihood
    on ``config.hyper_rows`` random rows of ``x`` (N, d), standardized by all of ``x``'s rows: scikit-learn's
    objective and optimizer, evaluated by ``gp_marginal`` (10x cheaper, one BLAS thread)."""
    from .gp_marginal import fit_hyperparameters, one_blas_thread

    config = config or GPConfig()
    x, y = _check_xy(x, y)
    mx, sx = _standardization(x)
    rows = _rows(len(x), config.hyper_rows, config.seed)
    z = (x[rows] - mx) / sx
    fits = []
    with one_blas_thread():
        for j in range(y.shape[1]):
            fits.append(fit_hyperparameters(z, y[rows, j], config.constant_bounds, config.length_scale_bounds,
                                            config.noise_bounds, config.noise_init))
    return GPHyperparameters(np.array([f[0] for f in fits], np.float64), np.array([f[1] for f in fits], np.float64),
                             np.array([f[2] for f in fits], np.float64), [f[3] for f in fits])


def condition_gp(x: np.ndarray, y: np.ndarray, hyper: GPHyperparameters, config: GPConfig | None = None,
                 meta: dict | None = None) -> "GPModel":
    """The GP with fixed ``hyper`` conditioned on at most ``config.rows`` random rows of (x, y),
    inputs standardized by all of ``x``'s rows. ``meta``: extra config entries (fields, robot)."""
    from sklearn.gaussian_process import GaussianProcessRegressor

    config = config or GPConfig()
    x, y = _check_xy(x, y)
    if hyper.length_scale.shape != (y.shape[1], x.shape[1]):
        raise UsageError(f"hyperparameters for {hyper.length_scale.shape} (outputs, inputs) do not fit data with "
                         f"{y.shape[1]} outputs and {x.shape[1]} inputs")
    mx, sx = _standardization(x)
    rows = _rows(len(x), config.rows, config.seed + 1)
    z = (x[rows] - mx) / sx
    alpha, y_mean, y_std = [], [], []
    for j in range(y.shape[1]):
        kernel = _sklearn_kernel(config, x.shape[1], hyper.constant[j], hyper.length_scale[j], hyper.noise_level[j])
        gp = GaussianProcessRegressor(kernel, optimizer=None, normalize_y=True).fit(z, y[rows, j])
        alpha.append(gp.alpha_)
        y_mean.append(gp._y_train_mean)  # sklearn's normalize_y statistics: the posterior mean's affine map
        y_std.append(gp._y_train_std)
    tensors = {"x_mean": mx, "x_std": sx, "z_train": np.array(z), "alpha": np.array(alpha),
               "constant": hyper.constant, "length_scale": hyper.length_scale, "noise_level": hyper.noise_level,
               "y_mean": np.array(y_mean, np.float64), "y_std": np.array(y_std, np.float64)}
    config_doc = {"format": GP_FORMAT, "format_version": GP_FORMAT_VERSION, "family": "gp", "gp": config.to_dict(),
                  "n_rows": int(len(rows)), "kernels": _describe(tensors),
                  "log_marginal_likelihood": list(hyper.log_marginal_likelihood), **(meta or {})}
    return GPModel({k: np.ascontiguousarray(v, np.float64) for k, v in tensors.items()}, config_doc)


def _check_xy(x, y) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    if y.ndim == 1:
        y = y[:, None]
    if x.ndim != 2 or y.ndim != 2 or len(x) != len(y) or len(x) < 2:
        raise UsageError(f"a GP needs x (N, d) and y (N, nv) with N >= 2 rows alike; got {x.shape} and {y.shape}")
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise UsageError("a GP's training data hold NaN or inf")
    return x, y


def _describe(tensors: dict) -> list[str]:
    """Each joint's fitted kernel in words (for the config and the report; not used to predict)."""
    return [f"{c:.4g} * RBF(length_scale=[{', '.join(f'{v:.3g}' for v in ls)}]) + WhiteKernel({s:.3g})"
            for c, ls, s in zip(tensors["constant"], tensors["length_scale"], tensors["noise_level"])]


# --------------------------------------------------------------------------- the model

class GPModel(SavedModel):
    """A fitted GP with the API of the PyTorch models (``TrainedModel``; both :class:`SavedModel`).

    ``predict(instances)``: one (T, nv) array per instance [Nm], every sample.
    ``predict_rows(x)``: (N, d) raw inputs -> (N, nv). ``config``: the dict in config.json.
    """

    window = 1
    FILES = GP_FILES

    def __init__(self, tensors: dict, config: dict, path: Path | None = None, train_seconds: float | None = None):
        _check_tensors(tensors, path or "GP model")
        super().__init__(config, path, train_seconds)
        self.tensors = tensors
        # Training inputs divided by each joint's length scales, once (as the kernel divides them).
        self._z_scaled = [tensors["z_train"] / ls for ls in tensors["length_scale"]]

    @property
    def gp_config(self) -> GPConfig:
        return GPConfig.from_dict(self.config["gp"])

    @property
    def inputs(self) -> list:
        return list(self.config["gp"]["inputs"])

    @property
    def targets(self) -> list:
        return [self.config["gp"]["target"]]

    @property
    def n_params(self) -> int:
        """Stored numbers the prediction uses (the training inputs and alpha dominate)."""
        return int(sum(t.size for t in self.tensors.values()))

    def predict_rows(self, x: np.ndarray) -> np.ndarray:
        """Posterior mean (N, nv) [target units] at raw inputs x (N, d), in blocks of PREDICT_CHUNK rows."""
        t = self.tensors
        x = np.asarray(x, np.float64)
        if x.ndim != 2 or x.shape[1] != t["x_mean"].shape[0]:
            raise ModelError(f"GP model expects inputs of width {t['x_mean'].shape[0]}, got shape {x.shape}")
        z = (x - t["x_mean"]) / t["x_std"]
        out = np.empty((len(z), t["alpha"].shape[0]))
        for s in range(0, len(z), PREDICT_CHUNK):
            zc = z[s:s + PREDICT_CHUNK]
            for j, (ls, zs) in enumerate(zip(t["length_scale"], self._z_scaled)):
                # k(x, Z) = c exp(-|(x - z)/l|^2 / 2); the white-noise term is zero between distinct points.
                k = t["constant"][j] * np.exp(-0.5 * cdist(zc / ls, zs, metric="sqeuclidean"))
                out[s:s + PREDICT_CHUNK, j] = t["y_std"][j] * (k @ t["alpha"][j]) + t["y_mean"][j]
        return out

    def predict(self, instances) -> list[np.ndarray]:
        """Predictions (T, nv) float64 [target units] for each instance."""
        instances = list(instances)
        if not instances:
            return []
        check_instances(instances, self.inputs, self.config.get("widths", {}), "GP model")
        x = np.concatenate([_inputs(inst, self.inputs) for inst in instances])
        return np.split(self.predict_rows(x), np.cumsum([len(i) for i in instances])[:-1])

    def evaluate(self, instances) -> dict:
        """RMSE [target units] and standardized MSE (by the training targets' std) on instances."""
        instances = list(instances)
        pred = np.concatenate(self.predict(instances))
        y = np.concatenate([_inputs(inst, self.targets) for inst in instances])
        err = pred - y
        scale = np.asarray(self.config.get("train_target_std", np.ones(y.shape[1])), np.float64)
        return {"loss": float(np.mean((err / scale) ** 2)), "rmse": float(np.sqrt(np.mean(err ** 2))),
                "rmse_per_component": np.sqrt(np.mean(err ** 2, axis=0)).tolist(),
                "max_abs_error": float(np.abs(err).max()), "n_samples": len(y)}

    def save(self, model_dir) -> None:
        save_gp(self, model_dir)


def _inputs(inst, names) -> np.ndarray:
    return np.concatenate([np.asarray(inst[n], np.float64).reshape(len(inst), -1) for n in names], axis=1)


def _xy(instances, config: GPConfig) -> tuple[np.ndarray, np.ndarray]:
    return (np.concatenate([_inputs(i, config.inputs) for i in instances]),
            np.concatenate([_inputs(i, [config.target]) for i in instances]))


def _check_tensors(tensors: dict, where) -> None:
    """The tensors a GP file must hold, with consistent shapes (n rows, d inputs, nv outputs)."""
    missing = sorted(set(TENSORS) - set(tensors))
    extra = sorted(set(tensors) - set(TENSORS))
    if missing or extra:
        raise ModelError(f"{where}: not a GP model file (missing tensors {missing}, unexpected {extra})")
    n, d = tensors["z_train"].shape if tensors["z_train"].ndim == 2 else (-1, -1)
    nv = tensors["alpha"].shape[0] if tensors["alpha"].ndim == 2 else -1
    expect = {"x_mean": (d,), "x_std": (d,), "z_train": (n, d), "alpha": (nv, n), "constant": (nv,),
              "length_scale": (nv, d), "noise_level": (nv,), "y_mean": (nv,), "y_std": (nv,)}
    wrong = [f"{k} {tuple(tensors[k].shape)} (expected {v})" for k, v in expect.items() if tuple(tensors[k].shape) != v]
    if wrong or min(n, d, nv) < 1:
        raise ModelError(f"{where}: GP tensors of inconsistent shapes: {', '.join(wrong) or 'empty'}")


# --------------------------------------------------------------------------- files

def save_gp(model: GPModel, model_dir, train_seconds: float | None = None,
            train_cpu_seconds: float | None = None) -> None:
    """Write model.safetensors, timing.json (when ``train_seconds``; with ``train_cpu_seconds`` [s] when
    known) and config.json, each through a
    per-run temporary and renamed into place; config.json last, so a folder with it is complete."""
    GP_FILES.write(model_dir, model.tensors, model.config, train_seconds, train_cpu_seconds)


def load_gp(model_dir, family: str = "gp") -> GPModel:
    """Open a GP model folder. Refuses a missing or partial folder, a model of another family
    (``family``: "gp", or "gp-residual" for the residual of a semiparametric GP, which alone predicts
    only the correction: ``gp_residual.load_gp_residual`` adds its prior), a config.json or tensors
    that do not match the digests saved with them."""
    model_dir = Path(model_dir)
    cpath, wpath = model_dir / "config.json", model_dir / "model.safetensors"
    config = GP_FILES.read_config(model_dir)
    if not isinstance(config, dict) or config.get("format") != GP_FORMAT:
        found = config.get("format") if isinstance(config, dict) else type(config).__name__
        raise ModelError(f"{model_dir} is not a GP model ({cpath} has format {found!r}, expected {GP_FORMAT!r}); "
                         f"a PyTorch model ('hybrid_dyn.model') loads with hybrid_dyn.learn.load_model")
    if config.get("family", "gp") != family:
        raise ModelError(f"{model_dir} is a {config.get('family')!r} model, not a {family!r} one"
                         + ("; load it with hybrid_dyn.learn.gp_residual.load_gp_residual (its prior added)"
                            if config.get("family") == "gp-residual" else ""))
    version = config.get("format_version", 0)
    if isinstance(version, bool) or not isinstance(version, int):  # "1" or null: refused, not a traceback
        raise ModelError(f"{cpath}: GP format_version must be an integer, got {version!r} (edited?)")
    if version > GP_FORMAT_VERSION:
        raise ModelError(f"{cpath}: GP format version {version} is newer than this toolkit's ({GP_FORMAT_VERSION})")
    meta, tensors = GP_FILES.read_tensors(model_dir)
    if meta.get("format") != GP_FORMAT:
        raise ModelError(f"{wpath} is not a GP model file (its metadata has format {meta.get('format')!r})")
    GP_FILES.check_config_digest(model_dir, config, meta)
    GP_FILES.check_tensors_digest(model_dir, meta, tensors)
    bad = sorted(k for k, v in tensors.items() if v.dtype != np.float64 or not np.isfinite(v).all())
    if bad:
        raise ModelError(f"{wpath}: tensors {bad} are not finite float64")
    return GPModel(tensors, config, path=model_dir, train_seconds=GP_FILES.train_seconds(model_dir, config))


# --------------------------------------------------------------------------- training on a dataset

def gp_fingerprint(config: GPConfig, dataset_checksum: str) -> str:
    return hashlib.sha256(canonical_json({"format_version": GP_FORMAT_VERSION, "gp": config.to_dict(),
                                          "dataset": dataset_checksum}).encode()).hexdigest()


def train_gp(dataset, out_dir, config: GPConfig | None = None, wait: bool = False) -> GPModel:
    """Fit a GP on ``dataset``'s train split (a Dataset or its path) and write it to ``out_dir``.

    A finished model of the same run there is returned as is; anything else there (another
    run, another model, files the toolkit did not write) is refused: nothing is overwritten.
    One run per folder: ``output_lock(out_dir)`` is held while fitting (``wait``: wait for another
    run's fit there instead of refusing).
    """
    config = config or GPConfig()
    config.validate()
    ds: Dataset = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
    out_dir = Path(out_dir)
    fingerprint = gp_fingerprint(config, ds.checksum)
    if (out_dir / "config.json").is_file():  # a finished model is never written again
        return _reuse(out_dir, fingerprint)
    with output_lock(out_dir, "GP model folder", wait=wait):
        if (out_dir / "config.json").is_file():  # finished by another run between the check and the lock
            return _reuse(out_dir, fingerprint)
        _refuse_foreign_files(out_dir)
        return _fit_locked(ds, out_dir, config, fingerprint)


def _fit_locked(ds: Dataset, out_dir: Path, config: GPConfig, fingerprint: str) -> GPModel:
    train, val = ds.split("train"), ds.split("val")
    if not train:
        raise UsageError(f"dataset {ds.path} has no training instances to fit a GP on")
    names = list(config.inputs) + [config.target]
    missing = sorted(set(names) - set(ds.fields))
    if missing:
        raise UsageError(f"dataset {ds.path} lacks fields {missing} that the GP needs (it has {sorted(ds.fields)})")
    widths = {n: int(np.asarray(train[0][n]).reshape(len(train[0]), -1).shape[1]) for n in names}
    check_instances(train + val, names, widths, "GP model")
    start, cpu0 = time.perf_counter(), time.process_time()  # process CPU: every BLAS thread counts
    x, y = _xy(train, config)
    hyper = fit_gp_hyperparameters(x, y, config)
    meta = {"robot": ds.meta.get("robot", "unknown"), "scenario": ds.meta.get("scenario"), "widths": widths,
            "dataset_checksum": ds.checksum, "fingerprint": fingerprint, "n_train_samples": int(len(x)),
            "train_target_std": y.std(0).tolist()}
    from .gp_marginal import one_blas_thread

    with one_blas_thread():  # an O(rows^3) factor: one thread beside torch's (gp_marginal.py)
        model = condition_gp(x, y, hyper, config, meta)
    if val:
        ev = model.evaluate(val)
        model.config.update(val_loss=ev["loss"], val_rmse=ev["rmse"])
    save_gp(model, out_dir, time.perf_counter() - start, time.process_time() - cpu0)
    return load_gp(out_dir)  # what the caller gets is what the file holds


def _reuse(out_dir: Path, fingerprint: str) -> GPModel:
    return GP_FILES.reuse(out_dir, fingerprint, load_gp)


def _refuse_foreign_files(out_dir: Path) -> None:
    """An output folder must be missing, empty, or hold only what a GP fit writes (``ModelFiles.is_own``)."""
    GP_FILES.refuse_foreign_files(out_dir)
