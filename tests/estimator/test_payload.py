"""A tool's load: bounded by the arm's rated payload, and changed between two calls without a restart.

The in-place change (``Robot.set_payload``) is checked against a robot loaded afresh with the load (the
URDF with the load as a link, parsed by Pinocchio), and the estimator on a stream whose ground truth is the
rigid-body model with the load from the moment it is picked up.
"""
from dataclasses import replace

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.analytic.methods import TIP_FORCE_METHODS
from hybrid_dyn.errors import UsageError
from hybrid_dyn.estimator import EstimatorStatus, TipForceEstimator
from hybrid_dyn.sim.sensors import read_sensors
from hybrid_dyn.sim.trust_streams import HARDWARE, kinematics

LOAD = (0.5, (0.02, -0.01, 0.05))  # kg, m in the tool frame


@pytest.fixture(scope="module")
def panda():
    return hd.load_robot("panda", num_threads=1)


# The stream is the model's own (no model error): the error bar's stated model term (estimator/model_term.py) has
# nothing to carry here, and the load declared is the one carried.
EXACT_MODEL = {"inertial_uncertainty": 0.0, "payload_uncertainty_kg": 0.0}


def test_a_payload_above_the_rated_one_is_refused_unless_overridden(panda):
    with pytest.raises(UsageError, match=r"payload 50 kg exceeds the rated payload of panda \(3 kg"):
        TipForceEstimator.analytic(panda, "base-wrench", payload=(50.0, (0, 0, 0)))
    est = TipForceEstimator.analytic(panda, "base-wrench", payload=(2.9, (0, 0, 0.05)))
    assert est.robot.payload.mass == 2.9
    with pytest.raises(UsageError, match="exceeds the rated payload"):
        est.set_payload(3.1)
    assert est.robot.payload.mass == 2.9  # a refused payload changes nothing
    with pytest.raises(UsageError, match="exceeds the rated payload"):  # a robot loaded with it, too
        TipForceEstimator(hd.load_robot("panda", payload=(4.0, (0, 0, 0))), "base-wrench")
    # A custom arm: the config's rating overrides the description's; a description without one: no bound.
    est = TipForceEstimator.analytic(panda, "base-wrench", payload=(5.0, (0, 0, 0)), rated_payload_kg=6.0)
    est.set_payload(6.0)
    with pytest.raises(UsageError, match=r"7 kg exceeds the rated payload of panda \(6 kg"):
        est.set_payload(7.0)
    unrated = panda.copy()
    unrated.spec = replace(panda.spec, rated_payload_kg=None)
    TipForceEstimator(unrated, "base-wrench").set_payload(40.0)
    with pytest.raises(UsageError, match="rated_payload_kg"):
        TipForceEstimator.analytic(panda, "base-wrench", rated_payload_kg=-1.0)


def test_a_payload_changed_in_place_is_a_robot_loaded_with_it(panda):
    rng = np.random.default_rng(3)
    q = np.array(panda.spec.home) + rng.uniform(-0.4, 0.4, (6, 7))
    qd, qdd = rng.normal(size=(6, 7)), rng.normal(size=(6, 7))
    est = TipForceEstimator.analytic(panda, "base-momentum")
    for load in (LOAD, (2.0, (0.0, 0.1, -0.03)), None):
        est.set_payload(*(load or (0.0,)))
        fresh = hd.load_robot("panda", payload=load, num_threads=1)
        robot = est.robot
        assert np.abs(robot.inverse_dynamics(q, qd, qdd) - fresh.inverse_dynamics(q, qd, qdd)).max() < 1e-9
        assert np.abs(robot.base_wrench(q, qd, qdd) - fresh.base_wrench(q, qd, qdd)).max() < 1e-9
        assert np.abs(robot.mass_matrix(q) - fresh.mass_matrix(q)).max() < 1e-9
        assert abs(robot.total_mass - fresh.total_mass) < 1e-12 and robot.name == fresh.name
        assert robot.urdf_xml == fresh.urdf_xml
    assert panda.payload is None and panda.name == "panda"  # the caller's robot is not the estimator's
    loaded = est.robot.base_wrench(q, qd, qdd)
    est.set_payload(*LOAD)
    assert np.abs(est.robot.base_wrench(q, qd, qdd) - loaded).max() > 1.0  # the change is seen


def _streams(robot, seconds=8.0, seed=4):
    """At 1 kHz, no contact: the arm moves 0.6-4.5 s and 5.5 s on, and at 5 s, standing still, its tool picks up
    LOAD. Truth: the rigid-body model without the load before, with it after. Returns the readings without
    the load and with it (the same kinematics and sensor draws), and the samples after the pick-up."""
    t = np.arange(int(seconds * 1000)) * 1e-3
    q, qd, qdd = kinematics(robot, t, ((0.6, 4.5), (5.5, seconds)), np.random.default_rng(seed))
    loaded = hd.load_robot("panda", payload=LOAD, num_threads=1)
    after = t >= 5.0
    tau, w = robot.inverse_dynamics(q, qd, qdd), robot.base_wrench(q, qd, qdd)
    bare = read_sensors(robot, HARDWARE, 1e-3, q, qd, tau, w, np.random.default_rng(seed + 1))
    tau[after] = loaded.inverse_dynamics(q[after], qd[after], qdd[after])
    w[after] = loaded.base_wrench(q[after], qd[after], qdd[after])
    return bare, read_sensors(robot, HARDWARE, 1e-3, q, qd, tau, w, np.random.default_rng(seed + 1)), after


def _run(robot, method, r, declare_at=None):
    """|F| [N] (the truth is 0) and whether each call was ok; set_payload(LOAD) before call declare_at."""
    est = TipForceEstimator.analytic(robot, method, **EXACT_MODEL)
    e, status = np.zeros(len(r.t)), []
    for k in range(len(r.t)):
        if k == declare_at:
            est.set_payload(*LOAD)
        f = est.estimate_tip_force(r.q[k], r.qd[k], base_wrench=r.base_wrench[k], tau_J=r.tau_J[k], t=r.t[k])
        e[k] = np.linalg.norm(f)
        status.append(est.last_status)
    return e, status


@pytest.mark.parametrize("method", list(TIP_FORCE_METHODS))
def test_a_load_declared_when_it_is_picked_up_errs_as_little_as_none_and_restarts_nothing(panda, method):
    bare, picked, after = _streams(panda)
    e0, s0 = _run(panda, method, bare)
    e1, s1 = _run(panda, method, picked, declare_at=int(np.argmax(after)))
    e2, _ = _run(panda, method, picked)
    ok0, ok1 = (np.array([s is EstimatorStatus.OK for s in x]) for x in (s0, s1))
    assert not any(s is EstimatorStatus.WARMING_UP for s, a in zip(s1, after) if a)  # no new window
    assert ok1[after].mean() > ok0[after].mean() - 0.02, (ok1[after].mean(), ok0[after].mean())
    rms = [float(np.sqrt(np.mean(e[after] ** 2))) for e in (e0, e1, e2)]
    assert rms[1] < rms[0] + 0.1 and rms[2] > 3.0, rms  # undeclared, the load's 4.9 N weight is a force
    assert e1[after & ok1].max() < e0[after & ok0].max() + 0.2
