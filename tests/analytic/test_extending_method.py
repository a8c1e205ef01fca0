"""A new estimator method, with a new bandwidth parameter, is one module (docs/extending.md).

The toy below is declared in one place (the ``toy`` fixture: its bandwidth parameter, the method, and a
residual net on it) and then found, unchanged, by every consumer: ``TipForceEstimator.analytic`` (its
parameter honoured, not silently "auto"), ``run_batch``, the bench's rows (``name`` and ``name-val``, the
latter built and run: before the bandwidth parameters were declarations it raised TypeError), the
residual priors and the preset rows. Unregistered, it leaves nothing behind.
"""
import numpy as np
import pytest
import scipy.signal

from hybrid_dyn.analytic.bandwidth import BANDWIDTHS, BandwidthParameter
from hybrid_dyn.analytic.batch_run import run_batch
from hybrid_dyn.analytic.method_declaration import Method, MethodStream
from hybrid_dyn.analytic.methods import TIP_FORCE_METHODS, residual_prior_names
from hybrid_dyn.analytic.observer_methods import BaseMomentumMethod
from hybrid_dyn.errors import UsageError
from hybrid_dyn.estimator import EstimatorConfig, EstimatorStatus, TipForceEstimator
from hybrid_dyn.sim.sensors import causal_acceleration

from helpers.motion import contact_stream

HZ = 1000.0


class StaticBase(MethodStream):
    """A toy: the quasi-static force from the base sensor alone, F = -(R w + m g), low-passed by K [1/s]."""

    def choose(self, noise):
        return 0.5 * self.rate_hz

    def reset(self):
        self._f = None

    def _raw(self, w):
        r = self.robot
        return -(r.base_wrench_to_root(w)[..., :3] + r.total_mass * np.asarray(r.model_ff.gravity.linear))

    def step(self, q, qd, qdd, w, tau):
        raw = self._raw(w)
        a = self.value * self.dt
        self._f = raw if self._f is None else self._f + a * (raw - self._f)
        return self._f.copy()

    def batch(self, q, qd, qdd, w, tau):
        raw, a = self._raw(np.asarray(w)), self.value * self.dt
        return scipy.signal.lfilter([a], [1.0, a - 1.0], raw, axis=0, zi=(1 - a) * raw[:1])[0]

    def settle_calls(self, sensors=()):
        return 7


def _toy_gains(rate_hz):
    return (0.05 * rate_hz, 0.5 * rate_hz)


@pytest.fixture
def toy():
    """The one place the toy is declared: a new bandwidth parameter, the method, a residual net on it."""
    from hybrid_dyn.learn.presets import PRESETS, TIP_INPUTS, Preset

    BANDWIDTHS.register(BandwidthParameter("toy_gain", "1/s", "the toy's low-pass gain K", _toy_gains))
    method = TIP_FORCE_METHODS.register(Method("static-base", "a toy", ("base_wrench",), False, False, True, "toy_gain",
                                               StaticBase, residual_prior=True))
    PRESETS.register(Preset("residual-static-base", "lstm", tuple(TIP_INPUTS), ("tip_force",), window=10,
                           front_units=(32,), prior="static-base", family="residual"))
    yield method
    _forget_toy()


def _forget_toy():
    """Unregister what the fixture declared and a test has not (the listeners remove what was derived)."""
    from hybrid_dyn.learn.presets import PRESETS

    if "residual-static-base" in PRESETS:
        PRESETS.unregister("residual-static-base")
    if "static-base" in TIP_FORCE_METHODS:
        TIP_FORCE_METHODS.unregister("static-base")
    if "toy_gain" in BANDWIDTHS:
        BANDWIDTHS.unregister("toy_gain")


def noisy_stream(robot, n, seed=0, hz=HZ):
    """A contact stream (sensor noise, a base-sensor offset, a constant 15 N contact from 0.8 s) as arrays:
    (t, q, qd, base wrench, tau_J, true force)."""
    samples, f = contact_stream(robot, n, hz=hz, seed=seed, contact_at=0.8)
    return (*(np.stack([s[k] for s in samples]) for k in ("t", "q", "qd", "base_wrench", "tau_J")), f)


def test_the_estimator_honours_a_new_bandwidth_parameter(toy, panda):
    t, q, qd, w, tau, f = noisy_stream(panda, 1500)

    def run(**settings):
        est = TipForceEstimator.analytic(panda, "static-base", call_hz=HZ, encoder_resolution=0.0, **settings)
        return est, np.stack([est.estimate_tip_force(q[k], qd[k], base_wrench=w[k], t=t[k]) for k in range(len(t))])

    est, out = run()  # "auto": the method's rule
    assert est.bandwidth == 0.5 * HZ and est.last_status is EstimatorStatus.OK
    # Physics: the arm moves slowly, so the quasi-static force is near the true one (the inertial part
    # is m J_com qdd: a few tenths of a newton here), far from the 15 N it is not.
    assert np.sqrt(np.mean(np.sum((out[1000:] - f[1000:]) ** 2, axis=1))) < 1.0
    fixed, out_fixed = run(toy_gain=40.0)  # its own parameter, by its declared name: used as is, no window
    assert fixed.bandwidth == 40.0 and fixed.config.bandwidth("toy_gain") == 40.0
    assert fixed.config == EstimatorConfig(call_hz=HZ, encoder_resolution=0.0, bandwidths={"toy_gain": 40.0})
    with pytest.raises(UsageError, match=r"toy_gain must be 'auto' or > 0 \[1/s\], got -1"):
        EstimatorConfig.from_settings(toy_gain=-1)
    with pytest.raises(UsageError, match="unknown bandwidth parameter 'toy_rate'"):
        EstimatorConfig(bandwidths={"toy_rate": 1.0})
    # run_batch reads the same declaration: by the rule, and at a fixed value
    batch, used = run_batch("static-base", panda, HZ, q, qd, w, None, encoder_resolution=0.0)
    assert used == 0.5 * HZ
    np.testing.assert_allclose(out[501:], batch[501:], atol=1e-9)  # the stream starts after its window
    batch_fixed, used_fixed = run_batch("static-base", panda, HZ, q, qd, w, None, value=40.0, encoder_resolution=0.0)
    assert used_fixed == 40.0 and not np.allclose(batch_fixed[600:], batch[600:])


def _bench_ctx(panda, tmp_path):
    from hybrid_dyn.bench.profiles import BenchProfile
    from hybrid_dyn.bench.plan import BenchContext
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset

    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=6, n_samples=150, record_hz=100.0,
                                             seed=3, noise=0.01, contact_free_s=0.6))
    return BenchContext(BenchProfile(name="t", scenarios=("log",)), "log", ds, panda, tmp_path / "work",
                        tmp_path / "data", log=lambda *a: None)


def test_the_bench_rows_of_a_new_method_build_and_run(toy, panda, tmp_path):
    from hybrid_dyn.bench.analytic_rows import PRIOR_ROWS
    from hybrid_dyn.bench.catalog import ROWS

    assert ROWS["static-base"].family == "analytic" and ROWS["static-base-val"].reference
    ctx = _bench_ctx(panda, tmp_path)
    test = ctx.dataset.split("test")
    for name in ("static-base", "static-base-val"):
        predictor = ROWS[name].build(ctx.dataset, ctx)
        forces = predictor.predict(test)
        # Samples before the method's first answer (its noise window) are refusals (NaN); every answer is finite.
        answered = ~np.isnan(forces[0]).all(axis=1)
        assert forces[0].shape == (len(test[0]["q"]), 3) and answered[-1] and np.all(np.isfinite(forces[0][answered]))
        assert answered[np.argmax(answered):].all()  # refused only before the first answer
        assert predictor.single_call(test[0], 0).shape == (3,)  # the user's TipForceEstimator, built
    assert "toy_gain" in predictor.inputs and "1/s (chosen on val)" in predictor.inputs
    assert ctx.cache[("chosen-on-val", "static-base toy_gain")] in _toy_gains(100.0)
    # as a residual prior: the method's declaration and one preset declaration
    assert "static-base" in residual_prior_names() and PRIOR_ROWS["static-base"] == "static-base"
    row = ROWS["residual-static-base"]
    assert row.family == "residual" and row.prior_row == "static-base" and row.trains


def test_a_new_method_as_a_residual_prior(toy, panda):
    from hybrid_dyn.learn.priors import PRIOR_FIELDS, AnalyticPrior

    t, q, qd, w, tau, f = noisy_stream(panda, 1500)
    batch, used = run_batch("static-base", panda, HZ, q, qd, w, None, encoder_resolution=0.0)
    assert PRIOR_FIELDS["static-base"] == ("q", "qd", "qdd", "base_wrench")
    prior = AnalyticPrior("static-base", panda, HZ, observer_gain=used, tare_seconds=0.5)
    qdd = causal_acceleration(qd, 1.0 / HZ, 20.0)  # what the stream's tare reads in its window
    np.testing.assert_allclose(prior.compute({"q": q, "qd": qd, "qdd": qdd, "base_wrench": w}), batch, atol=1e-9)


def test_unregistering_removes_everything_derived(toy):
    from hybrid_dyn.bench.analytic_rows import PRIOR_ROWS
    from hybrid_dyn.bench.catalog import ROWS
    from hybrid_dyn.learn.presets import PRESETS
    from hybrid_dyn.learn.priors import PRIOR_FIELDS

    PRESETS.unregister("residual-static-base")
    TIP_FORCE_METHODS.unregister("static-base")
    BANDWIDTHS.unregister("toy_gain")
    for name in ("static-base", "static-base-val", "residual-static-base"):
        assert name not in ROWS
    assert "static-base" not in PRIOR_ROWS and "static-base" not in PRIOR_FIELDS
    assert "static-base" not in TIP_FORCE_METHODS and "static-base" not in residual_prior_names()
    assert "toy_gain" not in BANDWIDTHS


def test_a_method_needs_its_bandwidth_parameter_declared():
    with pytest.raises(UsageError, match="bandwidth parameter 'toy_rate' is not declared"):
        TIP_FORCE_METHODS.register(Method("toy", "a toy", ("base_wrench",), False, False, True, "toy_rate", StaticBase))
    assert "toy" not in TIP_FORCE_METHODS


def test_a_method_may_not_take_a_torque_models_name():
    for name in ("rnea", "rnea-basewrench"):  # a torque model, and an older spelling of one
        with pytest.raises(UsageError, match=f"analytic estimator {name!r} is declared twice"):
            TIP_FORCE_METHODS.register(Method(name, "a toy", ("base_wrench",), False, False, True, "momentum_gain",
                                              StaticBase))
        assert name not in TIP_FORCE_METHODS


def test_a_method_has_no_prior_field():
    """``residual_prior`` is the one name (``prior`` names a residual model's analytic part); no release
    shipped the old field, so it is refused like any unknown one."""
    with pytest.raises(TypeError, match="prior"):
        Method("toy", "a toy", ("base_wrench",), False, False, True, "momentum_gain", StaticBase, prior=True)


def test_a_new_methods_module_can_import_the_declaration_without_an_import_circle():
    """A new method's module imports ``method_declaration`` (and may be imported by the catalogue): that module
    imports no method module and not the catalogue, so no circle can close through it; the catalogue imports
    every module of the package that registers a method."""
    import ast
    import inspect

    from hybrid_dyn.analytic import method_declaration, methods

    def imported(module):
        tree = ast.parse(inspect.getsource(module))
        return {a.name if node.module is None else node.module for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom) for a in node.names}

    registering = {m.make.__module__.rsplit(".", 1)[-1] for m in TIP_FORCE_METHODS.values()
                   if m.make.__module__.startswith("hybrid_dyn.analytic.")}  # the package's own (not a plugin's)
    assert "qdd_methods" in registering and "method_declaration" not in registering
    assert not (imported(method_declaration) & (registering | {"methods", "batch_run"}))
    assert registering <= imported(methods)


class _SlowRule(BaseMomentumMethod):
    """A derived method that differs only in its rule: a fifth of the base momentum observer's gain."""

    def choose(self, noise):
        super().choose(noise)
        self.value *= 0.2
        return self.value


class _Clipped(BaseMomentumMethod):
    """A derived method whose stream differs at any gain: the parent's force clipped to 2 N per axis."""

    def step(self, q, qd, qdd, w, tau):
        return np.clip(super().step(q, qd, qdd, w, tau), -2.0, 2.0)

    def batch(self, q, qd, qdd, w, tau):
        return np.clip(super().batch(q, qd, qdd, w, tau), -2.0, 2.0)


@pytest.mark.parametrize("stream, own_val", [(_Clipped, True), (_SlowRule, False)])
def test_a_derived_methods_val_row_is_chosen_on_its_own_stream(panda, tmp_path, stream, own_val):
    """``name-val`` is chosen and run on the method's own stream (its class, not its parent's): a derived
    method that behaves otherwise at a given gain gets a -val row of its own. The row fixes the gain to a
    grid value, which bypasses the rule (``MethodStream.close_window``), so one that differs only in its
    rule (docs/extending.md's half-gain) gets its parent's -val numbers while its own row differs."""
    from hybrid_dyn.bench.catalog import ROWS

    parent = TIP_FORCE_METHODS["base-momentum"]
    TIP_FORCE_METHODS.register(Method("derived-momentum", "a test's", parent.reads, parent.any_of, parent.needs_qdd,
                                      parent.tares, parent.parameter, stream))
    try:
        ctx = _bench_ctx(panda, tmp_path)
        test = ctx.dataset.split("test")
        got = {r: np.concatenate(ROWS[r].build(ctx.dataset, ctx).predict(test))
               for r in ("base-momentum", "derived-momentum", "base-momentum-val", "derived-momentum-val")}
        calls = {r: ROWS[r].build(ctx.dataset, ctx).single_call for r in ("base-momentum-val", "derived-momentum-val")}
        last = len(test[0]["q"]) - 1
        for k in range(last + 1):  # the user's call, stepped through one run
            single = {r: call(test[0], k) for r, call in calls.items()}
    finally:
        TIP_FORCE_METHODS.unregister("derived-momentum")
    assert ("chosen-on-val", "derived-momentum momentum_gain") in ctx.cache  # chosen for the method itself
    assert not np.allclose(got["derived-momentum"], got["base-momentum"], equal_nan=True)
    same_val = np.allclose(got["derived-momentum-val"], got["base-momentum-val"], equal_nan=True)
    assert same_val != own_val
    assert np.allclose(single["derived-momentum-val"], single["base-momentum-val"]) != own_val
