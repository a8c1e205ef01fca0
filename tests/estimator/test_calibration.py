"""The estimator on a torque model with friction and springs, and error bars calibrated on a log
(``estimator/torque_model.py``, ``estimator/calibration.py``, ``estimator/calibrate.py``).

Each result is checked against an independent path: the identification's own regressor prediction, a Monte
Carlo of the torque error through a least-squares solve, a synthetic law fitted back."""
from __future__ import annotations

import json

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.estimator import EstimatorStatus, TipForceEstimator
from hybrid_dyn.estimator.calibrate import first_order_lowpass, lead_in
from hybrid_dyn.estimator.calibration import (Calibration, CalibrationError, MethodCalibration, ModelError,
                                              fit_torque_error)
from hybrid_dyn.estimator.torque_model import JointTorqueModel
from hybrid_dyn.identify.identified_model import IdentifiedModel, LinearFriction
from hybrid_dyn.identify.regressor import nominal_body_parameters

HZ = 1000.0


def identified_file(robot, path, springs=None):
    """An identified parameter file of the nominal bodies with a known friction law (and springs)."""
    nv = robot.nv
    friction = LinearFriction(np.linspace(0.5, 1.5, nv), np.linspace(1.0, 2.0, nv), np.linspace(-0.3, 0.3, nv))
    body = nominal_body_parameters(robot).reshape(nv, 10)
    return IdentifiedModel(robot, "consistent", body, friction, springs=springs or {}).save(path), friction


def trajectory(robot, n=3000, hz=HZ):
    t = np.arange(n) / hz
    w = np.linspace(1.0, 2.0, robot.nv)
    q = np.array(robot.spec.home) + 0.3 * np.sin(w * t[:, None])
    qd = 0.3 * w * np.cos(w * t[:, None])
    qdd = -0.3 * w * w * np.sin(w * t[:, None])
    return t, q, qd, qdd


def test_the_torque_model_takes_from_tau_J_what_the_identification_added(panda, tmp_path):
    """The file's friction and springs, as the estimator subtracts them, equal the identified model's own
    prediction (regressor Y pi + friction + springs) less RNEA of the same bodies."""
    springs = {panda.joint_names[1]: [2.0, 5.0, -1.0]}
    path, _ = identified_file(panda, tmp_path / "id.json", springs)
    model = IdentifiedModel.load(path, panda)
    terms = JointTorqueModel.from_params(path, panda)
    assert terms.name == "identified+friction+springs"
    _, q, qd, qdd = trajectory(panda, 50)
    extra = np.array([terms.extra_torque(*x) for x in zip(q, qd, qdd)])
    np.testing.assert_allclose(extra, model.predict_torque(q, qd, qdd) - panda.inverse_dynamics(q, qd, qdd),
                               atol=1e-9)


def test_friction_in_tau_J_reads_as_force_unless_the_model_holds_it(panda, tmp_path):
    """tau_J carries friction, nothing touches the tool: with params= the estimator reads ~0 N; without the
    torque model (the old behaviour) the friction is a phantom of newtons."""
    path, friction = identified_file(panda, tmp_path / "id.json")
    t, q, qd, qdd = trajectory(panda)
    tau = panda.inverse_dynamics(q, qd, qdd) + friction(qd)
    out = {}
    for label, model in (("with", "params"), ("without", None)):
        est = TipForceEstimator.analytic(panda, "momentum-observer", params=path, torque_model=model, call_hz=HZ,
                                         encoder_resolution=0.0, momentum_gain=50.0, max_sigma=1e3)
        out[label] = np.array([est.estimate_tip_force(q[k], qd[k], tau_J=tau[k], t=t[k]) for k in range(len(t))])
    assert np.abs(out["with"][500:]).max() < 0.05
    assert np.linalg.norm(out["without"][500:], axis=1).mean() > 2.0


def test_the_model_term_is_the_torque_error_through_a_least_squares_solve(panda):
    """ModelError's sigma (closed form P Sigma P^T) equals the spread of lstsq(J_v^T, e) over samples e of the
    calibrated torque error, and grows without bound toward a stretched (singular) pose."""
    nv = panda.nv
    rng = np.random.default_rng(0)
    a = rng.normal(size=(nv, nv))
    corr = np.corrcoef(a @ a.T + nv * np.eye(nv))
    law = np.c_[np.linspace(0.2, 0.6, nv), np.full(nv, 0.1), np.full(nv, 0.02)]
    mc = MethodCalibration(5.0, law, corr, 1.3, 1.0, 0.5)
    me = ModelError(panda, mc)
    q, qd, qdd = np.array(panda.spec.home), np.full(nv, 0.5), np.full(nv, 2.0)
    sigma = me.update(q, qd, qdd)
    d = mc.joint_sigma(qd, qdd) * 1.3
    e = rng.multivariate_normal(np.zeros(nv), corr * np.outer(d, d), size=20000)
    jv = panda.tip_jacobian(q)[:3]
    f = np.linalg.lstsq(jv.T, e.T, rcond=None)[0].T
    np.testing.assert_allclose(sigma, f.std(axis=0), rtol=0.03)
    # Toward a stretched pose the weak direction's sigma grows as 1 / sigma_min(J_v): trace(P Sigma P^T) is at
    # least lambda_min(Sigma) / sigma_min^2 (P = pinv(J_v^T) has norm 1 / sigma_min).
    cov = corr * np.outer(d, d)
    for q4, q6 in ((-2.356, 1.571), (-0.5, 0.05)):
        pose = np.array(panda.spec.home)
        pose[[1, 3, 5]] = [0.0, q4, q6]
        me.reset()
        s2 = float(np.sum(me.update(pose, qd, qdd) ** 2))
        smin = np.linalg.svd(panda.tip_jacobian(pose)[:3], compute_uv=False)[-1]
        assert s2 >= np.linalg.eigvalsh(cov)[0] / smin ** 2


def test_a_known_error_law_is_fitted_back():
    rng = np.random.default_rng(1)
    n, nv = 40000, 3
    qd, qdd = rng.normal(0, 1.0, (n, nv)), rng.normal(0, 5.0, (n, nv))
    law = np.array([[0.3, 0.2, 0.05], [0.1, 0.0, 0.1], [0.5, 0.4, 0.0]])
    corr = np.array([[1.0, 0.6, 0.0], [0.6, 1.0, -0.3], [0.0, -0.3, 1.0]])
    z = rng.multivariate_normal(np.zeros(nv), corr, size=n)
    d = np.sqrt(law[:, 0] ** 2 + (law[:, 1] * qd) ** 2 + (law[:, 2] * qdd) ** 2)
    sig, r = fit_torque_error(d * z, qd, qdd)
    np.testing.assert_allclose(sig, law, atol=0.03)
    np.testing.assert_allclose(r, corr, atol=0.05)


def test_the_observer_low_pass_is_the_exact_first_order_step():
    """y' = K (x - y) for a step x = 1: y = 1 - exp(-K t) at every sample, whatever the steps."""
    t = np.cumsum(np.r_[0.0, np.random.default_rng(2).uniform(0.5e-3, 1.5e-3, 999)])
    y = first_order_lowpass(np.ones((1000, 2)), 5.0, np.diff(t))
    np.testing.assert_allclose(y[:, 0], np.r_[0.0, 1 - np.exp(-5.0 * t[1:])], atol=1e-12)


class _Inst(dict):
    def __init__(self, name, t):
        super().__init__(t=np.asarray(t, float))
        self.name = name


def test_the_lead_in_is_the_blocks_that_run_straight_into_the_part():
    blocks = [_Inst(f"b{i}", np.arange(i * 100, (i + 1) * 100) * 1e-3) for i in range(5)]
    assert [b.name for b in lead_in(blocks[:3], blocks[3:])] == ["b0", "b1", "b2"]
    other = [_Inst("x", np.arange(100) * 1e-3)]  # another trajectory, its time from 0: no lead-in
    assert lead_in(other, [_Inst("y", np.arange(100) * 1e-3)]) == []


def _calibration(robot, digest=None, method="momentum-observer"):
    nv = robot.nv
    mc = MethodCalibration(20.0, np.c_[np.full(nv, 0.2), np.zeros(nv), np.zeros(nv)], np.eye(nv), 1.0, 1.5, 0.4)
    return Calibration(robot.name, "rigid body", digest, np.zeros((nv, 3)), np.eye(nv), {method: mc})


def test_a_calibration_file_round_trips_and_is_refused_where_it_does_not_belong(panda, ur5, tmp_path):
    cal = _calibration(panda)
    path = cal.save(tmp_path / "cal.json")
    back = Calibration.load(path)
    assert back.to_dict() == cal.to_dict()
    with pytest.raises(CalibrationError, match="exists"):
        cal.save(path)  # never overwritten
    est = TipForceEstimator.analytic(panda, "momentum-observer", calibration=path, call_hz=HZ)
    assert est.max_sigma == 1.5 and est.bandwidth == 20.0  # no window: the calibrated bandwidth at once
    with pytest.raises(CalibrationError, match="robot 'panda', not 'ur5'"):
        TipForceEstimator.analytic(ur5, "momentum-observer", calibration=path, call_hz=HZ)
    with pytest.raises(CalibrationError, match="another torque model"):
        TipForceEstimator.analytic(panda, "momentum-observer", calibration=_calibration(panda, "abc"), call_hz=HZ)
    with pytest.raises(CalibrationError, match="no settings for method 'torques-pinv'"):
        TipForceEstimator.analytic(panda, "torques-pinv", calibration=path, call_hz=HZ)
    doc = json.loads(path.read_text())
    doc["methods"]["momentum-observer"]["torque_sigma"] = [[0.1, 0.0]] * 7
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(CalibrationError, match="torque_sigma must be"):
        Calibration.load(bad)
    (tmp_path / "cut.json").write_text(path.read_text()[:100])
    with pytest.raises(CalibrationError, match="cannot read"):
        Calibration.load(tmp_path / "cut.json")


def test_a_calibrated_error_bar_carries_the_model_term(panda):
    """With a calibration the error bar is at least the model term, and its bandwidth is the calibration's."""
    t, q, qd, qdd = trajectory(panda, 1500)
    tau = panda.inverse_dynamics(q, qd, qdd)
    est = TipForceEstimator.analytic(panda, "momentum-observer", calibration=_calibration(panda), call_hz=HZ,
                                     encoder_resolution=0.0)
    for k in range(len(t)):
        est.estimate_tip_force(q[k], qd[k], tau_J=tau[k], t=t[k])
    assert est.bandwidth == 20.0
    me = ModelError(panda, _calibration(panda).methods["momentum-observer"])
    # (the term is recomputed every 8 calls: within them the pose moves a fraction of a per cent of it)
    assert np.all(est.last_sigma >= 0.99 * me.update(q[-1], qd[-1], qdd[-1]))


def test_pc_stamps_stream_with_default_settings(panda):
    """A logging PC's stamps (steps 0.7-1.8 ms wandering by milliseconds about any clock, 6 % of them
    repeats of the last sample, four gaps of 8.5 ms): no exception, no refusal but at the gaps, and no warm-up
    after the first window."""
    rng = np.random.default_rng(3)
    n = 6000
    steps = rng.choice([0.8e-3, 0.9e-3, 1.0e-3, 1.1e-3, 1.2e-3, 1.3e-3, 1.6e-3, 1.8e-3], size=n,
                       p=[0.15, 0.25, 0.2, 0.15, 0.1, 0.08, 0.05, 0.02])
    steps[[1000, 2500, 4000, 5200]] = 8.5e-3
    t = np.cumsum(steps)
    _, q, qd, qdd = trajectory(panda, n)
    tau = panda.inverse_dynamics(q, qd, qdd)
    est = TipForceEstimator.analytic(panda, "momentum-observer", encoder_resolution=0.0, call_hz=HZ)
    status = []
    for k in range(n):
        est.estimate_tip_force(q[k], qd[k], tau_J=tau[k], t=t[k])  # on_bad_input="raise": any refusal raises
        status.append(est.last_status)
    warm = [k for k, s in enumerate(status) if s is EstimatorStatus.WARMING_UP]
    assert warm == list(range(len(warm))) and len(warm) < 600


def test_pc_stamps_refuse_only_a_long_gaps_end(panda):
    rng = np.random.default_rng(4)
    n = 3000
    t = np.cumsum(rng.uniform(0.7e-3, 1.7e-3, n))
    t[1000:] += 8e-3  # a short gap: bridged
    t[1500:] += 50e-3  # a long one: its end refused, the next sample confirms it and the method restarts
    _, q, qd, qdd = trajectory(panda, n)
    tau = panda.inverse_dynamics(q, qd, qdd)
    est = TipForceEstimator.analytic(panda, "momentum-observer", encoder_resolution=0.0, call_hz=HZ,
                                     on_bad_input="hold")
    status = []
    for k in range(n):
        est.estimate_tip_force(q[k], qd[k], tau_J=tau[k], t=t[k])
        status.append(est.last_status)
    refused = [k for k, s in enumerate(status) if s is EstimatorStatus.INPUT_REJECTED]
    assert refused == [1500]
    assert all(s is not EstimatorStatus.WARMING_UP for s in status[600:1500])
    assert status[1501] is EstimatorStatus.WARMING_UP


def test_hd_load_robot_and_estimate_from_a_params_file_of_another_robot_is_refused(panda, ur5, tmp_path):
    path, _ = identified_file(panda, tmp_path / "id.json")
    with pytest.raises(hd.description.RobotDescriptionError, match="identified for robot"):
        JointTorqueModel.from_params(path, ur5)


@pytest.mark.parametrize("method", ["torques-pinv", "momentum-observer"])
def test_a_pose_in_the_damped_region_is_no_promise(panda, method):
    """At a pose where J_v's least singular value lies inside the damped solve's region, a 10 N push along the
    weak direction is read shrunk: the status says so (never ``ok``), while a pose outside it is ``ok``."""
    from hybrid_dyn.analytic.tip_force import SINGULAR_REGION

    near = np.array([0.0, -0.7, 0.0, -0.52, 0.0, 3.0, 0.785])
    u, s, vt = np.linalg.svd(panda.tip_jacobian(near)[:3])
    assert s[-1] < SINGULAR_REGION  # the weak direction: u[:, -1]
    for q0, expect in ((near, EstimatorStatus.NEAR_SINGULARITY), (np.array(panda.spec.home), EstimatorStatus.OK)):
        push = 10.0 * np.linalg.svd(panda.tip_jacobian(q0)[:3])[0][:, -1]
        tau = panda.inverse_dynamics(q0, np.zeros(7), np.zeros(7)) - panda.tip_jacobian(q0)[:3].T @ push
        est = TipForceEstimator.analytic(panda, method, call_hz=HZ, encoder_resolution=0.0, max_sigma=1e3)
        noise = np.random.default_rng(5).normal(0, 1e-3, (1500, 7))  # a live sensor: never frozen
        free = panda.inverse_dynamics(q0, np.zeros(7), np.zeros(7))
        for k in range(1500):  # the push after the start-up window, which tares the joint torques' offsets
            f = est.estimate_tip_force(q0, np.zeros(7), tau_J=(tau if k >= 700 else free) + noise[k], t=k / HZ)
        assert est.last_status is expect, (method, est.last_status)
        if expect is EstimatorStatus.OK:
            np.testing.assert_allclose(f, push, atol=0.05)
        else:
            assert np.linalg.norm(f) < 9.0  # the damped solve's shrunk reading, which no "ok" may carry


@pytest.mark.parametrize("method", ["momentum-observer", "base-momentum"])
def test_a_q_off_the_declared_encoder_grid_is_told_and_read_as_given(panda, method):
    """The Panda's description declares 1e-5 rad encoders; a log of the arm's own q and qd (off that grid) is
    warned of once and read as given: the estimates agree with an estimator told encoder_resolution=0. A q on the grid
    (the simulator's hardware read) is filtered, with no warning."""
    from hybrid_dyn.estimator.tip_force_estimator import EncoderModelWarning

    t, q, qd, qdd = trajectory(panda, 1200)
    tau, w = panda.inverse_dynamics(q, qd, qdd), panda.base_wrench(q, qd, qdd)
    kw = lambda k: {"tau_J": tau[k]} if method == "momentum-observer" else {"base_wrench": w[k]}  # noqa: E731
    default = TipForceEstimator.analytic(panda, method, call_hz=HZ)
    exact = TipForceEstimator.analytic(panda, method, call_hz=HZ, encoder_resolution=0.0)
    with pytest.warns(EncoderModelWarning, match="off the grid of the declared encoder resolution 1e-05 rad"):
        a = np.array([default.estimate_tip_force(q[k], qd[k], t=t[k], **kw(k)) for k in range(len(t))])
    b = np.array([exact.estimate_tip_force(q[k], qd[k], t=t[k], **kw(k)) for k in range(len(t))])
    # (the grid is left at the call whose q first falls off it: a tared method's window then starts a few calls
    # later than the exact estimator's, so the two agree once both settle)
    np.testing.assert_allclose(a[1100:], b[1100:], atol=0.02)
    assert default.encoder_mismatch is not None and default.encoder_resolution == 0.0
    on_grid = np.round(q / 1e-5) * 1e-5
    quantized = TipForceEstimator.analytic(panda, method, call_hz=HZ)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", EncoderModelWarning)
        for k in range(len(t)):
            if k not in (600, 601):  # a short gap: its bridged samples lie off the grid by construction, unchecked
                quantized.estimate_tip_force(on_grid[k], qd[k], t=t[k], **kw(k))
    assert quantized.encoder_mismatch is None and quantized.encoder_resolution == 1e-5


def test_a_timed_stream_at_another_rate_is_said_to_be_one(panda):
    """Steps of 0.5 ms (a 2 kHz stream) or 1.6 ms each lie within the stamp tolerance of a 1 kHz period, one by one;
    their running mean does not: the status says "wrong rate", never ok. A PC's 0.8-1.3 ms steps are no wrong rate."""
    rng = np.random.default_rng(8)
    for steps, wrong in ((np.full(1500, 0.5e-3), True), (np.full(1500, 1.6e-3), True),
                         (rng.choice([0.8e-3, 0.9e-3, 1.0e-3, 1.1e-3, 1.3e-3], 1500), False)):
        t = np.cumsum(steps)
        est = TipForceEstimator.analytic(panda, "momentum-observer", call_hz=HZ, encoder_resolution=0.0,
                                         on_bad_input="hold")
        q, tau = np.array(panda.spec.home), panda.inverse_dynamics(np.array(panda.spec.home), np.zeros(7), np.zeros(7))
        noise = rng.normal(0, 1e-3, (len(t), 7))
        status = [est.estimate_tip_force(q, np.zeros(7), tau_J=tau + noise[k], t=t[k]) is not None and est.last_status
                  for k in range(len(t))]
        assert (EstimatorStatus.WRONG_RATE in status[100:]) is wrong
        assert EstimatorStatus.OK not in status[100:] or not wrong


@pytest.mark.parametrize("t", [10 ** 400, "0.061", b"1"])
def test_a_stamp_that_is_no_float_is_refused_by_name(panda, t):
    est = TipForceEstimator.analytic(panda, "momentum-observer", call_hz=HZ, encoder_resolution=0.0)
    with pytest.raises(hd.estimator.EstimatorInputError, match="t must be a number"):
        est.estimate_tip_force(np.array(panda.spec.home), np.zeros(7), tau_J=np.zeros(7), t=t)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(methods=[]), "must be tables"),
    (lambda d: d.update(version=99), "version 99"),
    (lambda d: d.pop("robot"), r"needs \['robot'\]"),
    (lambda d: d["methods"]["momentum-observer"].update(bandwidth=0.0), "bandwidth = 0.0"),
    (lambda d: d["methods"]["momentum-observer"].update(sigma_scale=float("nan")), "sigma_scale = nan"),
    (lambda d: d["methods"]["momentum-observer"].update(max_sigma=-1.0), "max_sigma = -1.0"),
    (lambda d: d["methods"]["momentum-observer"]["correlation"][0].__setitem__(1, 50.0), "correlation matrix"),
    (lambda d: d["source"].update(not_calibrated=["x"]), "must be tables"),
])
def test_a_calibration_file_with_bad_contents_is_refused_by_name(panda, tmp_path, edit, message):
    path = _calibration(panda).save(tmp_path / "cal.json")
    doc = json.loads(path.read_text())
    edit(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(CalibrationError, match=message):
        Calibration.load(bad)


def test_an_identified_file_of_another_tool_is_refused(tmp_path):
    """A file identified on the bare flange (panda[tool=none]) holds no hand in its last body: the Panda with its
    hand is another robot for it."""
    bare = hd.load_robot("panda[tool=none]")
    path, _ = identified_file(bare, tmp_path / "id.json")
    assert JointTorqueModel.from_params(path, bare) is not None
    with pytest.raises(hd.description.RobotDescriptionError, match="with this tool"):
        JointTorqueModel.from_params(path, hd.load_robot("panda"))
