"""Every estimator method declared once (``TIP_FORCE_METHODS``), and what is built from it; each test runs
on every registered method, so a new method meets these contracts with no edit here.

- (a toy method registered in one place is found everywhere: test_extending_method.py);
- each method's streaming step (the user's TipForceEstimator) equals its batch run on the same samples;
- no filter design or Riccati solve runs inside ``estimate_tip_force``, the window-closing call included.
"""
import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from hybrid_dyn.analytic import kalman
from hybrid_dyn.analytic.batch_run import run_batch
from hybrid_dyn.analytic.methods import TIP_FORCE_METHODS
from hybrid_dyn.estimator import EstimatorStatus, TipForceEstimator

from helpers.motion import contact_stream

HZ = 1000.0


def noisy_stream(robot, n, seed=0, hz=HZ):
    """The status tests' contact stream (sensor noise, a base-sensor offset, a constant 15 N contact from
    0.8 s) as arrays: (t, q, qd, base wrench, tau_J, true force)."""
    samples, f = contact_stream(robot, n, hz=hz, seed=seed, contact_at=0.8)
    return (*(np.stack([s[k] for s in samples]) for k in ("t", "q", "qd", "base_wrench", "tau_J")), f)


@pytest.mark.parametrize("method", list(TIP_FORCE_METHODS))
# A control loop's 1 kHz, and the reference study's 20 Hz logs: there Nyquist (10 Hz) is below the 20 Hz filter the
# noise window runs at 1 kHz, so the window's filter is at 0.45 x the rate. settled: contact at 0.8 s, plus 0.3 s
# (1 kHz) or 1.2 s (20 Hz: the slowest filters and observers settle in tens of samples).
@pytest.mark.parametrize("hz, n, settled", [(HZ, 1400, 1100), (20.0, 200, 40)])
def test_streaming_step_equals_the_batch_run(method, hz, n, settled, panda):
    """The user's call, sample by sample, against the method's batch run over the whole stream (the tare
    as a running mean and the window's noise as running sums, against the whole window's arrays)."""
    t, q, qd, w, tau, f = noisy_stream(panda, n, seed=3, hz=hz)
    spec = TIP_FORCE_METHODS[method]
    kw = lambda k: {name: x[k] for name, x in (("base_wrench", w), ("tau_J", tau)) if name in spec.reads}  # noqa: E731
    # the stream is the model's own: run_batch's error bar carries no stated model term, nor does this one
    est = TipForceEstimator.analytic(panda, method, call_hz=hz, encoder_resolution=0.0, inertial_uncertainty=0.0)
    out = np.stack([est.estimate_tip_force(q[k], qd[k], t=t[k], **kw(k)) for k in range(len(t))])
    batch, used = run_batch(method, panda, hz, q, qd, w if "base_wrench" in spec.reads else None,
                            tau if "tau_J" in spec.reads else None, encoder_resolution=0.0)
    assert used == pytest.approx(est.bandwidth, rel=1e-9) and est.last_status is EstimatorStatus.OK
    window = int(0.5 * hz)  # the noise window: the stream starts after it
    np.testing.assert_allclose(out[window:], batch[window:], atol=1e-7)
    # ...and a real estimate of the 15 N contact once settled.
    assert np.sqrt(np.mean(np.sum((out[settled:] - f[settled:]) ** 2, axis=1))) < 1.0


def test_no_design_or_riccati_solve_runs_in_a_call(monkeypatch, panda):
    """Counted: scipy's Butterworth design and discrete Riccati solver, from construction on. None may
    run in any call, the window-closing one included (the rule picks among designs made at construction)."""
    t, q, qd, w, tau, f = noisy_stream(panda, 700)
    estimators = {m: TipForceEstimator.analytic(panda, m, call_hz=HZ, encoder_resolution=0.0) for m in TIP_FORCE_METHODS}
    calls = {"butter": 0, "dare": 0}

    def counting(name, fn):
        def wrapped(*a, **k):
            calls[name] += 1
            return fn(*a, **k)
        return wrapped

    monkeypatch.setattr(scipy.signal, "butter", counting("butter", scipy.signal.butter))
    monkeypatch.setattr(scipy.linalg, "solve_discrete_are", counting("dare", scipy.linalg.solve_discrete_are))
    monkeypatch.setattr(kalman, "solve_discrete_are", counting("dare", kalman.solve_discrete_are))
    scipy.signal.butter(2, 10.0, fs=HZ)  # the counters count
    assert calls["butter"] == 1
    for m, est in estimators.items():
        for k in range(len(t)):
            est.estimate_tip_force(q[k], qd[k], base_wrench=w[k], tau_J=tau[k], t=t[k])
        assert est.bandwidth is not None, m  # the window closed
    assert calls == {"butter": 1, "dare": 0}



@pytest.mark.parametrize("method", [m.name for m in TIP_FORCE_METHODS.where(tares=True)])
def test_a_press_held_while_the_tool_moves_is_refused_alike_by_the_stream_and_the_batch(method, panda):
    """12 N held at the tool from t = 0 to 1.2 s while the arm moves (the rigid-body reaction, base_wrench
    with tip_force): the base sensor's force cannot tell it from its offset, its moments can. Both the
    streaming window and run_batch refuse the windows the press lies in, and agree on what follows."""
    from helpers.motion import CONTACT_SENSORS, sine_motion
    from hybrid_dyn.sim.sensors import read_sensors

    rng = np.random.default_rng(7)
    n = 2500
    t = np.arange(n) / HZ
    q, qd, qdd = sine_motion(panda, t, rng, (0.15, 0.3))
    f = np.where(t[:, None] < 1.2, np.array([0.6, -0.3, -0.74]) / np.linalg.norm([0.6, -0.3, -0.74]) * 12.0, 0.0)
    jv = panda.tip_jacobian(q)[:, :3]
    tau = panda.inverse_dynamics(q, qd, qdd) - np.einsum("nij,ni->nj", jv, f)
    r = read_sensors(panda, CONTACT_SENSORS, 1.0 / HZ, q, qd, tau, panda.base_wrench(q, qd, qdd, tip_force=f), rng)
    spec = TIP_FORCE_METHODS.lookup(method)
    kw = lambda k: {name: x[k] for name, x in (("base_wrench", r.base_wrench), ("tau_J", r.tau_J))  # noqa: E731
                    if name in spec.reads}
    est = TipForceEstimator.analytic(panda, method, call_hz=HZ, encoder_resolution=0.0)
    out, status = [], []
    for k in range(n):
        out.append(est.estimate_tip_force(r.q[k], r.qd[k], t=r.t[k], **kw(k)))
        status.append(est.last_status)
    out = np.array(out)
    assert EstimatorStatus.CONTACT_AT_START in status[500:1200] and EstimatorStatus.OK not in status[:1200]
    batch, _ = run_batch(method, panda, HZ, r.q, r.qd, r.base_wrench if "base_wrench" in spec.reads else None,
                         r.tau_J if "tau_J" in spec.reads else None, encoder_resolution=0.0)
    assert not batch[:1500].any()  # the batch's forces are 0 until its first trusted window ends, too
    np.testing.assert_allclose(out[2000:], batch[2000:], atol=1e-7)
    assert np.abs(out[-300:] - f[-300:]).max() < 1.5  # released: the tare did not keep the press
