"""The semiparametric GP: an identified model plus a sparse GP on its residual.

The design in full: ``docs/design/learn.md`` (gp_residual.py).
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from scipy.spatial.distance import cdist

from ..data.dataset import Dataset, load_dataset
from ..errors import UsageError
from ..outputs import output_lock
from .gp import (GP_FORMAT, GP_FORMAT_VERSION, GPConfig, GPModel, STD_EPS, _inputs, _refuse_foreign_files, _rows,
                 _standardization, fit_gp_hyperparameters, load_gp, save_gp)
from .gp_marginal import one_blas_thread
from .trained_model import ModelError, canonical_json, check_instances

FAMILY = "gp-residual"
CHUNK = 4096  # training rows per kernel block when accumulating K(Z, X) K(X, Z)


@dataclass
class GPResidualConfig:
    """How the residual GP is fitted.

    hyper_rows: training rows of the marginal-likelihood fit (O(n^3) per L-BFGS step).
    inducing: inducing inputs M (fit O(N M^2), memory O(M^2 + CHUNK M)).
    length_scale_factors, noise_factors: the candidates around the fitted (l, s), chosen on val.
    max_rows: training rows the sparse fit reads, at most (random, by seed): the fit is O(max_rows M^2)
    per candidate, so a simulated bench set of 10^5 samples costs what 2 x 10^4 do (the real Panda's
    12,328 training rows are all read).
    seed: picks the hyperparameter rows, the inducing rows and the fit's rows. inputs, target: dataset fields.
    """

    hyper_rows: int = 600
    # Chosen on the real Panda's validation blocks (time-ordered split), never its test blocks, by
    # benchmarks/gp_residual_control.py (retired after commit 87faae1): validation RMSE 0.3011 / 0.2934 /
    # 0.2834 / 0.2782 Nm at M = 500 / 1000 / 2000 / 4000 (the prior alone 0.3166), 4000 fitting in 932 s
    # against 196 s on a shared 2-core machine. The fitted s sat at its lower bound (1e-6) on some joints
    # and validation chose s x 1000 there: the grid reaches x 1e4.
    inducing: int = 2000
    length_scale_factors: tuple = (0.25, 0.5, 1.0)
    noise_factors: tuple = (1.0, 10.0, 100.0, 1000.0, 10000.0)
    max_rows: int = 20000
    seed: int = 0
    inputs: tuple = ("q", "qd", "qdd")
    target: str = "tau_m"

    def __post_init__(self):
        self.inputs = tuple(self.inputs)
        self.length_scale_factors = tuple(float(v) for v in self.length_scale_factors)
        self.noise_factors = tuple(float(v) for v in self.noise_factors)
        problems = [f"{k} must be an integer >= 1, got {getattr(self, k)!r}"
                    for k in ("hyper_rows", "inducing", "max_rows")
                    if not (isinstance(getattr(self, k), int) and getattr(self, k) >= 1)]
        for k in ("length_scale_factors", "noise_factors"):
            if not getattr(self, k) or min(getattr(self, k)) <= 0:
                problems.append(f"{k} must be positive numbers, got {getattr(self, k)!r}")
        if problems:
            raise UsageError("invalid GPResidualConfig: " + "; ".join(problems))

    def gp_config(self) -> GPConfig:
        return GPConfig(hyper_rows=self.hyper_rows, rows=self.inducing, seed=self.seed, inputs=self.inputs,
                        target=self.target)

    def to_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> "GPResidualConfig":
        known = {f.name for f in fields(cls)}
        if set(d) - known:
            raise ModelError(f"unknown GPResidualConfig keys {sorted(set(d) - known)}; known: {sorted(known)}")
        return cls(**d)


# --------------------------------------------------------------------------- fitting (arrays)


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a^-1 b for a symmetric positive (semi)definite a, with growing jitter if Cholesky fails."""
    scale = float(np.mean(np.diag(a))) or 1.0
    for jitter in (1e-10, 1e-8, 1e-6, 1e-4):
        try:
            return cho_solve(cho_factor(a + jitter * scale * np.eye(len(a))), b)
        except LinAlgError:
            continue
    raise ModelError("the sparse GP's system is not positive definite even with jitter 1e-4")


def _scaled_sq_distances(a: np.ndarray, b: np.ndarray, length_scale: np.ndarray) -> np.ndarray:
    """|(a - b) / l|^2 for every pair of rows: the kernel's distance at length scale l. A candidate l x f
    has distance d / f^2, so one matrix serves every length-scale factor of a joint."""
    return cdist(a / length_scale, b / length_scale, metric="sqeuclidean")


def _gram_terms(z, z_m, ys, c, ls, factors) -> tuple[list, list]:
    """Per length-scale factor f: K(Z, X) K(X, Z) and K(Z, X) y at length scale ls x f, accumulated over blocks
    of CHUNK training rows (K(X, Z) is never held whole); the distances of a block are computed once for all f.
    (A symmetric rank-k update, BLAS syrk, measured slower than the full product here: 0.47 s against 0.33 s
    for a 4096 x 2000 block on one thread.)"""
    m = len(z_m)
    grams, k_y = [np.zeros((m, m)) for _ in factors], [np.zeros(m) for _ in factors]
    for s in range(0, len(z), CHUNK):
        d = _scaled_sq_distances(z[s:s + CHUNK], z_m, ls)
        for i, f in enumerate(factors):
            k_nm = c * np.exp(d * (-0.5 / f**2))
            grams[i] += k_nm.T @ k_nm
            k_y[i] += k_nm.T @ ys[s:s + CHUNK]
    return grams, k_y


def _val_mse(zv, z_m, c, ls, factors, ws: list, y_std: float, y_mean: float, r_val: np.ndarray) -> list:
    """Validation MSE [Nm^2] per length-scale factor f of ``factors`` and per column of ws[i] (M, K) (one per
    noise candidate), K(Zv, Z) built in blocks of CHUNK rows: a paper-size validation split (6e5 rows x 2000
    inducing) would need 10 GB at once."""
    sq = [np.zeros(w.shape[1]) for w in ws]
    for s in range(0, len(zv), CHUNK):
        d = _scaled_sq_distances(zv[s:s + CHUNK], z_m, ls)
        for i, f in enumerate(factors):
            pred = y_std * ((c * np.exp(d * (-0.5 / f**2))) @ ws[i]) + y_mean
            sq[i] += np.sum((pred - r_val[s:s + CHUNK, None]) ** 2, axis=0)
    return [v / len(zv) for v in sq]


def fit_sparse_residual(x: np.ndarray, r: np.ndarray, x_val: np.ndarray, r_val: np.ndarray,
                        config: GPResidualConfig, hyper=None) -> tuple[dict, list]:
    """The residual GP's tensors (``gp.TENSORS``) and the per-joint choice, from training inputs x (N, d),
    residuals r (N, nv) [Nm] and their validation counterparts. See the module docstring. ``hyper``:
    hyperparameters already fitted on (x, r) (``gp.fit_gp_hyperparameters``), else they are fitted here."""
    x, r, x_val, r_val = (np.asarray(a, np.float64) for a in (x, r, x_val, r_val))
    if len(x_val) == 0:
        raise UsageError("the residual GP chooses its hyperparameters on the validation split: it is empty")
    hyper = hyper if hyper is not None else fit_gp_hyperparameters(x, r, config.gp_config())
    mx, sx = _standardization(x)  # as fit_gp_hyperparameters standardized: the same length scales apply
    z, zv = (x - mx) / sx, (x_val - mx) / sx
    z_m = z[_rows(len(z), config.inducing, config.seed + 1)]
    y_mean, y_std = r.mean(0), r.std(0) + STD_EPS
    nv, factors = r.shape[1], config.length_scale_factors
    alpha, length_scale, noise = np.zeros((nv, len(z_m))), hyper.length_scale.copy(), hyper.noise_level.copy()
    out_mean, choice = np.zeros(nv), []
    for j in range(nv):
        ys = (r[:, j] - y_mean[j]) / y_std[j]
        c, ls = float(hyper.constant[j]), hyper.length_scale[j]
        prior_mse = float(np.mean(r_val[:, j] ** 2))  # the prior alone: a zero residual
        best = {"val_mse": prior_mse, "kept_prior": True, "val_mse_prior": prior_mse}
        grams, k_y = _gram_terms(z, z_m, ys, c, ls, factors)
        d_mm, ws = _scaled_sq_distances(z_m, z_m, ls), []
        for f, gram, ky in zip(factors, grams, k_y):
            k_mm = c * np.exp(d_mm * (-0.5 / f**2))
            ws.append(np.stack([_solve(float(hyper.noise_level[j]) * nf * k_mm + gram, ky)
                                for nf in config.noise_factors], axis=1))
        mses = _val_mse(zv, z_m, c, ls, factors, ws, y_std[j], y_mean[j], r_val[:, j])
        for lf, w_lf, mse_lf in zip(factors, ws, mses):  # candidates in the order they always were tried
            for k, (nf, mse) in enumerate(zip(config.noise_factors, mse_lf)):
                if mse < best["val_mse"]:
                    best = {"val_mse": float(mse), "kept_prior": False, "val_mse_prior": prior_mse,
                            "length_scale_factor": lf, "noise_factor": nf, "w": w_lf[:, k]}
        if not best["kept_prior"]:
            alpha[j], out_mean[j] = best.pop("w"), y_mean[j]
            length_scale[j] = hyper.length_scale[j] * best["length_scale_factor"]
            noise[j] = hyper.noise_level[j] * best["noise_factor"]
        choice.append({"joint": j + 1, **best})
    tensors = {"x_mean": mx, "x_std": sx, "z_train": z_m, "alpha": alpha, "constant": hyper.constant,
               "length_scale": length_scale, "noise_level": noise, "y_mean": out_mean, "y_std": y_std}
    return {k: np.ascontiguousarray(v, np.float64) for k, v in tensors.items()}, choice


# --------------------------------------------------------------------------- the model

class GPResidualModel:
    """An identified model plus a residual GP: predictions [Nm] of the motor torque tau_m.

    ``prior``: the :class:`IdentifiedModel`; ``residual``: a :class:`GPModel` of the residual.
    ``predict(instances)``: one (T, nv) array per instance; ``predict_rows(x)``: x = [q, qd, qdd] (N, 3 nv).
    """

    window = 1

    def __init__(self, prior, residual: GPModel):
        self.prior, self.residual = prior, residual
        self.config = residual.config
        self.path = residual.path

    @property
    def inputs(self) -> list:
        return self.residual.inputs

    @property
    def targets(self) -> list:
        return self.residual.targets

    @property
    def n_params(self) -> int:
        return self.residual.n_params + int(self.prior.body_params.size)

    @property
    def train_seconds(self) -> float:
        return self.residual.train_seconds

    @property
    def kept_prior(self) -> list[bool]:
        """Per joint: whether validation kept the prior (a zero residual)."""
        return [bool(c["kept_prior"]) for c in self.config["selection"]]

    def predict_rows(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, np.float64)
        nv = self.prior.robot.nv
        prior = self.prior.predict_torque(x[:, :nv], x[:, nv:2 * nv], x[:, 2 * nv:3 * nv])
        return prior + self.residual.predict_rows(x)

    def predict(self, instances) -> list[np.ndarray]:
        instances = list(instances)
        residuals = self.residual.predict(instances)
        return [self.prior.predict_torque(i.q, i.qd, i.qdd) + r for i, r in zip(instances, residuals)]


def _sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def load_gp_residual(model_dir, robot=None) -> GPResidualModel:
    """Open a residual GP folder and its prior; refuses a prior file that changed since the fit."""
    from ..identify.identified_model import IdentifiedModel

    residual = load_gp(model_dir, family=FAMILY)
    prior = residual.config.get("prior")
    if residual.config.get("family") != FAMILY or not isinstance(prior, dict):
        raise ModelError(f"{model_dir} is not a residual GP (family {residual.config.get('family')!r}); "
                         f"a plain GP loads with hybrid_dyn.learn.gp.load_gp")
    path = Path(prior["params"])
    if not path.is_file():
        raise ModelError(f"{model_dir}: its prior, the identified parameter file {path}, is missing")
    if _sha256(path) != prior["params_sha256"]:
        raise ModelError(f"{model_dir}: its prior {path} changed since the fit (sha256 differs); refit")
    return GPResidualModel(IdentifiedModel.load(path, robot=robot), residual)


def train_gp_residual(dataset, params, out_dir, config: GPResidualConfig | None = None, robot=None) -> GPResidualModel:
    """Fit the residual GP of the identified parameter file ``params`` on ``dataset``'s train split, choose
    on its val split, write it to ``out_dir``; a finished model of the same run there is returned as is."""
    from ..identify.identified_model import IdentifiedModel

    config = config or GPResidualConfig()
    ds: Dataset = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
    params, out_dir = Path(params).resolve(), Path(out_dir)
    fingerprint = hashlib.sha256(canonical_json({"format_version": GP_FORMAT_VERSION, "family": FAMILY,
                                                 "config": config.to_dict(), "dataset": ds.checksum,
                                                 "params_sha256": _sha256(params)}).encode()).hexdigest()
    with output_lock(out_dir, "GP model folder"):
        if (out_dir / "config.json").is_file():  # a finished model is never written again
            model = load_gp_residual(out_dir, robot=robot)
            if model.config.get("fingerprint") != fingerprint:
                raise ModelError(f"{out_dir} holds a residual GP of another run (other config, data or prior); "
                                 "choose another output folder or delete it")
            return model
        _refuse_foreign_files(out_dir)
        prior = IdentifiedModel.load(params, robot=robot)
        train, val = ds.split("train"), ds.split("val")
        names = list(config.inputs) + [config.target]
        missing = sorted(set(names) - set(ds.fields))
        if missing or not train:
            raise UsageError(f"dataset {ds.path}: a residual GP needs training instances with {names} "
                             f"(missing fields {missing})")
        widths = {n: int(np.asarray(train[0][n]).reshape(len(train[0]), -1).shape[1]) for n in names}
        check_instances(train + val, names, widths, "residual GP")
        start, cpu0 = time.perf_counter(), time.process_time()  # process CPU: every BLAS thread counts
        (x, r), (xv, rv) = (_residual_xy(prior, insts, config) for insts in (train, val))
        if len(x) > config.max_rows:  # all rows when they are few enough: the same rows, in order
            keep = _rows(len(x), config.max_rows, config.seed + 2)
            x, r = x[keep], r[keep]
        with one_blas_thread():  # O(N M^2) products and M x M factors: one thread beside torch's (gp_marginal.py)
            tensors, choice = fit_sparse_residual(x, r, xv, rv, config)
        doc = {"format": GP_FORMAT, "format_version": GP_FORMAT_VERSION, "family": FAMILY,
               "gp": config.gp_config().to_dict(), "gp_residual": config.to_dict(), "widths": widths,
               "prior": {"params": str(params), "params_sha256": _sha256(params), "method": prior.method,
                         "robot": prior.robot.name},
               "selection": choice, "n_train_samples": int(len(x)), "n_inducing": int(len(tensors["z_train"])),
               "robot": ds.meta.get("robot", "unknown"), "scenario": ds.meta.get("scenario"),
               "dataset_checksum": ds.checksum, "fingerprint": fingerprint,
               "val_rmse_prior": float(np.sqrt(np.mean([c["val_mse_prior"] for c in choice]))),
               "val_rmse": float(np.sqrt(np.mean([c["val_mse"] for c in choice])))}
        save_gp(GPModel(tensors, doc), out_dir, time.perf_counter() - start, time.process_time() - cpu0)
    return load_gp_residual(out_dir, robot=robot)  # what the caller gets is what the file holds


def _residual_xy(prior, instances, config: GPResidualConfig) -> tuple[np.ndarray, np.ndarray]:
    """Inputs (N, d) and residuals tau_m - prior (N, nv) [Nm] of ``instances``."""
    if not instances:
        return np.zeros((0, 1)), np.zeros((0, 1))
    x = np.concatenate([_inputs(i, config.inputs) for i in instances])
    r = np.concatenate([np.asarray(i[config.target], np.float64) - prior.predict_torque(i.q, i.qd, i.qdd)
                        for i in instances])
    return x, r
