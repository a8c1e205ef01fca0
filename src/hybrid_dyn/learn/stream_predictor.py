"""A trained tip-force model driven one sample at a time (for ``TipForceEstimator``).

The model was trained on input windows of L samples recorded at ``record_hz``. A
control loop calls faster (``call_hz``, e.g. 1 kHz). We keep a ring of the last
(L-1)*k + 1 calls, k = call_hz / record_hz, and hand the model every k-th of
them ending at the newest: each call gets a fresh estimate from an input window with
the training spacing. At start-up the ring is filled with the first sample, as
training edge-padded every instance.

The analytic part comes with the model: per-sample priors (base-wrench, RNEA)
are evaluated on the newest sample; the momentum prior is an observer stepped
at every call. A tared base-wrench prior tares the sensor on the first
``tare_seconds`` of calls, as training did on each instance's start
(``analytic/tare.py``): the arm must not be touched then.

Out of range: an input more than ``RANGE_SIGMAS`` training standard deviations
from its training mean (any q, qd, qdd, wrench or torque component) makes the
estimate "input out of training range" (``EstimatorStatus.OUT_OF_RANGE``); it is still returned.
"""
from __future__ import annotations

import copy
import warnings
from pathlib import Path

import numpy as np
import torch

from ..analytic.acceleration import default_qdd_cutoff
from ..analytic.methods import TIP_FORCE_METHODS
from ..analytic.tare import StreamingTare, tare_samples, tared_runs
from ..data.input_windows import window_index
from ..errors import UsageError
from ..timing import median_call_us
from .trained_model import ModelError, TrainedModel, load_model
from .priors import AnalyticPrior

RANGE_SIGMAS = 5.0


class _ArrayInstance:
    """Arrays that look like a dataset Instance to ``TrainedModel`` (one run)."""

    def __init__(self, fields: dict):
        self.fields = [k for k, v in fields.items() if v is not None]
        self._f = {k: np.asarray(v, float) for k, v in fields.items() if v is not None}
        self.name = "arrays"

    def __getitem__(self, key):
        return self._f[key]

    def __len__(self):
        return len(self._f["q"])


class _OnnxNet:
    """The network part exported to ONNX, run by onnxruntime on one thread (float32).

    For one input window onnxruntime's compiled LSTM is about twice as fast as the
    numba kernels (benchmarks/export_speed.py); it computes in float32.
    """

    def __init__(self, net, input_window: int, n_in: int):
        import io

        import onnxruntime as ort

        buf = io.BytesIO()
        x = torch.zeros(1, input_window, n_in)
        with warnings.catch_warnings():  # the TorchScript-based exporter warns about its own future
            warnings.simplefilter("ignore")
            torch.onnx.export(net.eval(), (x,), buf, input_names=["x"], output_names=["y"], dynamo=False)
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = 1
        opts.inter_op_num_threads = 1
        self._session = ort.InferenceSession(buf.getvalue(), opts, providers=["CPUExecutionProvider"])
        self._x = np.empty((1, input_window, n_in), np.float32)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self._x[0] = x
        return self._session.run(None, {"x": self._x})[0][0].astype(np.float64)


def _median_call_seconds(fn, x, n: int = 200) -> float:
    """Median time of one call ``fn(x)`` [s], after one untimed call (``timing.median_call_us``)."""
    return median_call_us(lambda: fn(x), n, warmup=1) * 1e-6


class StreamingModel:
    """runtime: "numba" (float64, agrees with the batch path to round-off), "onnx"
    (onnxruntime, float32) or "auto": time both at load and keep the faster."""

    def __init__(self, model: TrainedModel, call_hz: float | None = None, runtime: str = "auto"):
        if list(model.targets) != ["tip_force"]:
            raise ModelError(f"model {model.preset.name!r} predicts {model.targets}, not the tip force")
        self.model = model
        self.robot = model.robot
        self.inputs = list(model.inputs)
        self.widths = [model.config["widths"][f] for f in self.inputs]
        self.window = model.window
        self.record_hz = float(model.config.get("record_hz") or 100.0)
        # The filter training's qdd went through [Hz] (``train.qdd_provenance``): None for exact qdd, and for
        # a log or an older model that does not say (the stream then uses its own default filter, which is
        # the generator's 20 Hz at every rate above 44 Hz, as before the config recorded it).
        qdd = model.config.get("qdd") or {}
        self.qdd_cutoff_hz = None if qdd.get("cutoff_hz") is None else float(qdd["cutoff_hz"])
        m = model.module
        self._x_mean = m.x_mean.double().numpy()
        self._x_std = m.x_std.double().numpy()
        self._x_inv_std = 1.0 / self._x_std
        self._y_mean = m.y_mean.double().numpy()
        self._y_std = m.y_std.double().numpy()
        self._row = np.empty(sum(self.widths))
        self._slices = []
        i = 0
        for name, w in zip(self.inputs, self.widths):
            self._slices.append((name, i, i + w))
            i += w
        # The control-loop path: the ring holds standardised rows (one 25-value
        # operation per call instead of a whole window), fed straight to the
        # numba network. DeLaN goes through the model's own single-sample path.

        self._fast = None
        self.runtime = "pytorch (DeLaN)"
        self._prior_kind = model.preset.prior
        self._method = self._prior_stream = None
        self.set_call_rate(call_hz or self.record_hz)
        if m.delan is None:
            self._choose_runtime(runtime)
        self._warm_up()

    def stream_qdd_cutoff(self, call_hz: float) -> float:
        """The qdd filter [Hz] a stream at ``call_hz`` runs for this model: training's filter, or for exact or
        unrecorded qdd the stream's own causal estimate (``default_qdd_cutoff``). A training filter at or
        above the stream's Nyquist frequency cannot be run: refused, naming the filter and the rate."""
        if self.qdd_cutoff_hz is None:
            return default_qdd_cutoff(call_hz)
        if not self.qdd_cutoff_hz < 0.5 * call_hz:
            raise UsageError(f"model {self.model.path} saw qdd through a {self.qdd_cutoff_hz:g} Hz filter in training, "
                             f"which a stream at call_hz={call_hz:g} Hz cannot reproduce (its Nyquist frequency is "
                             f"{0.5 * call_hz:g} Hz): call at a multiple of its training rate above "
                             f"{2 * self.qdd_cutoff_hz:g} Hz, or pass qdd_cutoff_hz below call_hz / 2 to accept "
                             "another filter than training's")
        return self.qdd_cutoff_hz

    @classmethod
    def load(cls, model_dir: Path, robot: str | None = None, call_hz: float | None = None,
             runtime: str = "auto") -> "StreamingModel":
        return cls(load_model(model_dir, robot=robot), call_hz, runtime)

    def _choose_runtime(self, runtime: str) -> None:
        """Set the network runtime. "auto" times whole ``step`` calls (analytic part
        included) with each: in a loop that also runs Pinocchio, onnxruntime's
        larger working set can lose an advantage it shows on the network alone."""
        from .fastpath import FastNet

        if runtime not in ("auto", "numba", "onnx"):
            raise ModelError(f"runtime must be auto, numba or onnx, got {runtime!r}")
        net = self.model.module.net
        candidates = {}
        if runtime in ("auto", "numba"):
            candidates["numba"] = FastNet(net)
        if runtime in ("auto", "onnx"):
            candidates["onnx"] = _OnnxNet(net, self.window, sum(self.widths))
        timings = {}
        for name, fast in candidates.items():
            self._fast, self.runtime = fast, name
            if len(candidates) > 1:
                timings[name] = _median_call_seconds(lambda _: self._warm_up(steps=20), None, n=15)
        if timings:
            best = min(timings, key=timings.get)
            self._fast, self.runtime = candidates[best], best

    # ---------------------------------------------------------------- timing
    def set_call_rate(self, call_hz: float) -> None:
        ratio = call_hz / self.record_hz
        self.stride = max(1, int(round(ratio)))
        # Slower than training (ratio < 1) used to pass with stride 1: a window spanning
        # 1/ratio times the training time, and a momentum prior stepped at the wrong dt.
        if not ratio > 0 or abs(ratio - self.stride) > 1e-6 * ratio:
            raise ModelError(f"call rate {call_hz} Hz must be the training rate {self.record_hz:g} Hz "
                             "or an integer multiple of it")
        self.call_hz = call_hz
        self._ring = np.empty(((self.window - 1) * self.stride + 1, len(self._row)))
        self._offsets = np.arange(self.window - 1, -1, -1) * self.stride  # oldest first
        n = len(self._ring)  # the ring rows of the window ending at each head: one take per call
        self._window_rows = (np.arange(n)[:, None] - self._offsets) % n
        # A registered method as the prior: its one definition, stepped at the call rate with the
        # bandwidth the model was trained with (a filter: stepped at every call).
        self._method = TIP_FORCE_METHODS.get(self.model.preset.prior)
        self._prior_stream = None
        if self._method is not None:
            self._prior_stream = self._method.make(self.robot, call_hz)
            self._prior_stream.configure(self.model.config.get("observer_gain", 20.0))
        # One tare for the net's base-wrench input and the prior's (the same contact-free start).
        self._tare = None
        tare_seconds = max(self.model.sensor_tare_seconds,
                           self.model.prior.tare_seconds if self.model.prior is not None else 0.0)
        if tare_seconds > 0:
            self._tare = StreamingTare(self.robot, tare_samples(call_hz, tare_seconds))
        self._tare_input = self.model.sensor_tare_seconds > 0
        self.reset()

    def warmup_calls(self, call_hz: float) -> int:
        """Calls until the window holds only real samples (and the observer has settled)."""
        if call_hz != self.call_hz:
            self.set_call_rate(call_hz)
        n = (self.window - 1) * self.stride + 1
        if self._method is not None and self._method.stateful:
            settle = 1 + self._prior_stream.settle_calls(self._method.reads)
            # A filter on the tared sensor starts after the tare window (``AnalyticPrior``).
            tare = self._tare.n_calls if self._tare is not None and self.model.prior.tare_seconds > 0 else 0
            n = max(n, tare + settle)
        if self._tare is not None:
            n = max(n, self._tare.n_calls)
        return n

    def reset(self) -> None:
        self._head = -1
        if self._prior_stream is not None:
            self._prior_stream.reset()
        if self._tare is not None:
            self._tare.reset()

    def _warm_up(self, steps: int = 1) -> None:
        """Compile the numba kernels and touch every buffer now, not in the first control cycle."""
        nv = self.robot.nv
        q = np.clip(np.zeros(nv), self.robot.q_lower, self.robot.q_upper)
        z = np.zeros(nv)
        w = self.robot.base_wrench(q, z, z)
        for _ in range(steps):
            self.step(q, z, z, w, z, None)
        self.reset()

    def _prior_at(self, q, qd, qdd, base_wrench, tau_J, in_tare):
        """The analytic part at this sample; base_wrench already tared (when the prior tares)."""
        kind = self._prior_kind
        if kind is None:
            return None
        if self._method is not None:  # the sample is validated (``step``): the method's own step
            if in_tare and self._method.stateful and self.model.prior.tare_seconds > 0:
                # a filter on the tared sensor: 0 in the tare window, then from a fresh start
                return np.zeros(3)
            return self._prior_stream.step(q, qd, qdd, base_wrench, tau_J)
        return self.model.prior.single({"q": q, "qd": qd, "qdd": qdd, "base_wrench": base_wrench})

    # ------------------------------------------------------------------ step
    def step(self, q, qd, qdd, base_wrench, tau_J, t) -> tuple[np.ndarray, bool]:
        """One validated sample in; (tip force (3,) [N], inside the training range?) out."""
        in_tare = self._tare is not None and not self._tare.done
        w_tared = base_wrench if self._tare is None else self._tare.update(q, qd, qdd, base_wrench)
        values = {"q": q, "qd": qd, "qdd": qdd, "base_wrench": w_tared if self._tare_input else base_wrench,
                  "tau_J": tau_J}
        row = self._row
        for name, a, b in self._slices:
            row[a:b] = values[name]
        row -= self._x_mean
        row *= self._x_inv_std  # standardised, as the network saw it in training
        n = len(self._ring)
        if self._head < 0:
            self._ring[:] = row  # edge padding, as in training
            self._head = 0
        else:
            self._head = (self._head + 1) % n
            self._ring[self._head] = row
        x = self._ring.take(self._window_rows[self._head], axis=0)  # = ring[(head - offsets) % n]
        prior = self._prior_at(q, qd, qdd, w_tared, tau_J, in_tare)
        if self._fast is not None:
            f = self._y_std * self._fast(x)
            f += self._y_mean if prior is None else prior
        else:
            f = self.model.predict_window(x * self._x_std + self._x_mean, prior=prior)
        in_range = float(np.abs(row).max()) <= RANGE_SIGMAS
        return f, in_range

    # ----------------------------------------------------------------- batch
    def predict_arrays(self, q, qd, qdd, base_wrench=None, tau_J=None) -> np.ndarray:
        """Batch predictions (N, 3) [N] over one run of samples, in float64.

        Same windows as training (edge-padded); float64 so that it agrees with
        the streaming path (also float64) to round-off.
        """
        inst = _ArrayInstance({"q": q, "qd": qd, "qdd": qdd, "base_wrench": base_wrench, "tau_J": tau_J})
        self.model._check_instances([inst])
        module64 = copy.deepcopy(self.model.module).double()
        seen = tared_runs([inst], self.robot, self.call_hz, self.model.sensor_tare_seconds)[0]
        x_all = np.concatenate([np.asarray(seen[f], float).reshape(len(inst), -1) for f in self.inputs], axis=1)
        index = window_index([len(inst)], self.window)
        prior = None
        if self.model.prior is not None:
            p = self.model.prior
            if self._method is not None and self._method.stateful:  # a filter: at the call rate
                p = AnalyticPrior(p.kind, self.robot, self.call_hz, p.observer_gain, p.tare_seconds, p.friction)
            prior = torch.from_numpy(p.compute({k: inst[k] for k in p.fields}))
        with torch.no_grad():
            out = module64(torch.from_numpy(x_all[index]), prior)
        return out.numpy()
