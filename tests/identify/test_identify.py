"""Identification: regressor, base parameters, estimators, files, excitation.

References are independent of the code under test: DART's inverse dynamics for
the data, Pinocchio's Inertia class and numpy eigenvalues for the parameter
checks, finite differences for the trajectory derivatives.
"""
import json

import numpy as np
import pinocchio as pin
import pytest

import hybrid_dyn as hd
from hybrid_dyn.description import RobotDescriptionError
from hybrid_dyn.identify import (IdentifiedModel, LinearFriction, base_parameters, friction_from_file,
                                 full_regressor, identify, inertial_regressor)
from hybrid_dyn.identify.identification_methods import IDENTIFICATION_METHODS
from hybrid_dyn.identify.parameters import (dynamic_to_log_cholesky, from_urdf_form, log_cholesky_to_pseudo,
                                            pseudo_to_dynamic, to_urdf_form)
from hybrid_dyn.identify.regressor import nominal_body_parameters
from hybrid_dyn.sim.plant import DartPlant

from helpers.states import random_states

MISMATCH_PAYLOAD = (0.5, (0.0, 0.0, 0.05))


def smooth_motion(robot, n, seed, dt=0.01, speed=1.0):
    """A multi-sine joint motion (q, qd, qdd) of n samples inside the limits."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)[:, None] * dt
    lo = np.maximum(robot.q_lower, -np.pi) + 0.3
    hi = np.minimum(robot.q_upper, np.pi) - 0.3
    q, qd, qdd = np.broadcast_to((lo + hi) / 2, (n, robot.nv)).copy(), np.zeros((n, robot.nv)), np.zeros((n, robot.nv))
    for k in (1, 2, 3, 5):
        w = 2 * np.pi * 0.12 * k * speed
        amp = rng.uniform(-1, 1, robot.nv) * (hi - lo) / 8 / np.sqrt(k)
        ph = rng.uniform(0, 2 * np.pi, robot.nv)
        q += amp * np.sin(w * t + ph)
        qd += amp * w * np.cos(w * t + ph)
        qdd -= amp * w**2 * np.sin(w * t + ph)
    return q, qd, qdd


@pytest.fixture(scope="module")
def mismatch_plant():
    return hd.load_robot("panda", params="franka_official", payload=MISMATCH_PAYLOAD)


# ------------------------------------------------------------------- parameters
def test_parameter_forms_agree_with_pinocchio():
    rng = np.random.default_rng(0)
    for _ in range(5):
        inertia = pin.Inertia.Random()
        pi = inertia.toDynamicParameters()
        m, c, icom = to_urdf_form(pi)
        assert m == pytest.approx(inertia.mass)
        np.testing.assert_allclose(c, inertia.lever, atol=1e-12)
        i3 = inertia.inertia
        np.testing.assert_allclose(icom, [i3[0, 0], i3[0, 1], i3[0, 2], i3[1, 1], i3[1, 2], i3[2, 2]], atol=1e-12)
        np.testing.assert_allclose(from_urdf_form(m, c, icom), pi, atol=1e-12)
    assert rng is not None


def test_log_cholesky_gives_consistent_bodies_and_inverts():
    import casadi as ca

    rng = np.random.default_rng(1)
    for _ in range(20):
        theta = rng.normal(size=10) * np.array([1, 1, 1, 1, 0.5, 0.5, 0.5, 0.3, 0.3, 0.3]) - np.array([0, 2, 2, 2, 0, 0, 0, 0, 0, 0])
        pi = np.asarray(pseudo_to_dynamic(log_cholesky_to_pseudo(ca.DM(theta)))).ravel()
        inertia = pin.Inertia.FromDynamicParameters(pi)
        eig = np.linalg.eigvalsh(inertia.inertia)
        assert inertia.mass > 0 and eig.min() > 0
        assert eig[0] + eig[1] >= eig[2] - 1e-12  # triangle inequality (sorted eigenvalues)
        np.testing.assert_allclose(dynamic_to_log_cholesky(pi), theta, atol=1e-7)


# -------------------------------------------------------------------- regressor
def test_symbolic_regressor_matches_pinocchio(described_robot):
    from hybrid_dyn.identify.symbolic import regressor_function

    robot = described_robot
    Yf = regressor_function(robot)
    q, qd, qdd = random_states(robot, 5, seed=3)
    for i in range(5):
        np.testing.assert_allclose(np.array(Yf(q[i], qd[i], qdd[i])), inertial_regressor(robot, q[i], qd[i], qdd[i]),
                                   atol=1e-10)


def _assert_regressor_times_body_parameters_is_dart(robot) -> None:
    """The robot's regressor times its model's body parameters is DART's inverse dynamics on that model."""
    plant = DartPlant(robot)
    pi = nominal_body_parameters(robot)
    q, qd, qdd = random_states(robot, 5, seed=4)
    for i in range(5):
        assert np.abs(inertial_regressor(robot, q[i], qd[i], qdd[i]) @ pi
                      - plant.inverse_dynamics(q[i], qd[i], qdd[i])).max() < 1e-9


def test_regressor_times_nominal_parameters_is_dart_inverse_dynamics(described_robot):
    """Every declared robot: its regressor times its URDF's body parameters is DART's inverse dynamics."""
    _assert_regressor_times_body_parameters_is_dart(described_robot)


def test_regressor_times_parameters_is_dart_inverse_dynamics(mismatch_plant):
    """The mismatched plant (other parameters than the URDF's): the same identity on its own parameters."""
    _assert_regressor_times_body_parameters_is_dart(mismatch_plant)


def test_base_parameters_reproduce_the_full_model(panda):
    base = base_parameters(panda)
    # The Panda has 43 identifiable inertial combinations (Gaz et al. 2019) + 3 friction terms per joint.
    q, qd, qdd = random_states(panda, 60, seed=11)  # other states than the QR used
    W = full_regressor(panda, q, qd, qdd).reshape(60 * panda.nv, -1)
    assert base.n_base == np.linalg.matrix_rank(W) == 43 + 21
    x = np.random.default_rng(2).normal(size=W.shape[1])
    np.testing.assert_allclose(base.reduce(W) @ base.project(x), W @ x, atol=1e-9)


# ------------------------------------------------------------------- estimators
def _dart_torques(robot, q, qd, qdd, friction=None):
    plant = DartPlant(robot)
    tau = np.stack([plant.inverse_dynamics(q[i], qd[i], qdd[i]) for i in range(len(q))])
    return tau + (friction(qd) if friction is not None else 0.0)


def test_ols_recovers_base_parameters_on_noise_free_plant_data(panda, mismatch_plant):
    """Known plant (other inertials, payload, linear friction); torques from DART, not Pinocchio."""
    nv = panda.nv
    rng = np.random.default_rng(5)
    friction = LinearFriction(rng.uniform(0.1, 0.5, nv), rng.uniform(0.2, 1.0, nv), rng.uniform(-0.2, 0.2, nv))
    q, qd, qdd = random_states(panda, 150, seed=6)
    tau = _dart_torques(mismatch_plant, q, qd, qdd, friction)
    model = identify((q, qd, qdd, tau), "ols", panda)
    base = base_parameters(panda)
    truth = np.concatenate([nominal_body_parameters(mismatch_plant),
                            np.stack([friction.fv, friction.fc, friction.fo], 1).ravel()])
    beta_true = base.project(truth)
    beta_hat = np.array(model.fit["base_parameters"]["values"])
    rel = np.abs(beta_hat - beta_true) / np.maximum(np.abs(beta_true), 1e-12)
    assert rel.max() < 1e-6, (rel.max(), np.argmax(rel))
    q2, qd2, qdd2 = random_states(panda, 40, seed=7)
    err = model.predict_torque(q2, qd2, qdd2) - _dart_torques(mismatch_plant, q2, qd2, qdd2, friction)
    assert np.abs(err).max() < 1e-6


def _independent_validity(pi):
    """mass > 0, inertia about the COM positive definite, triangle inequalities: via Pinocchio + numpy."""
    inertia = pin.Inertia.FromDynamicParameters(np.asarray(pi, float))
    eig = np.linalg.eigvalsh(inertia.inertia)
    return inertia.mass > 0 and eig.min() > 0 and eig[0] + eig[1] > eig[2]


@pytest.fixture(scope="module")
def noisy_mismatch_data(panda, mismatch_plant):
    """Mismatch-ext-like data: manufacturer inertials + 0.5 kg tool + Gaz friction, noisy torques."""
    gaz = panda.spec.friction("gaz2019")
    q, qd, qdd = smooth_motion(panda, 1500, seed=8, speed=1.5)
    rng = np.random.default_rng(9)
    tau = mismatch_plant.inverse_dynamics(q, qd, qdd) + gaz(qd) + 0.05 * rng.normal(size=q.shape)
    return q, qd, qdd, tau


def test_consistent_is_physically_valid_where_ols_may_not_be(panda, noisy_mismatch_data, tmp_path):
    ols = identify(noisy_mismatch_data, "ols", panda)
    cons = identify(noisy_mismatch_data, "consistent", panda)
    valid_ols = [_independent_validity(p) for p in ols.body_params]
    valid_cons = [_independent_validity(p) for p in cons.body_params]
    # On this data OLS gives some bodies impossible inertials: the check below discriminates.
    assert not all(valid_ols), valid_ols
    assert all(valid_cons), valid_cons
    assert cons.physically_consistent
    # COM inside the box around each link.
    assert all(r.com_in_box for r in cons.consistency())
    # It fits about as well as the unconstrained fit (same friction model).
    r_ols, r_cons = np.array(ols.fit["rmse_per_joint"]), np.array(cons.fit["rmse_per_joint"])
    assert np.sqrt(np.mean(r_cons**2)) < 1.5 * np.sqrt(np.mean(r_ols**2)) + 0.02
    # The file loads as a robot (Pinocchio and DART) that predicts what the model predicts.
    path = cons.save(tmp_path / "cons.json")
    robot = hd.load_robot("panda", params=path)
    q, qd, qdd = random_states(panda, 10, seed=10)
    np.testing.assert_allclose(robot.inverse_dynamics(q, qd, qdd) + friction_from_file(path)(qd),
                               cons.predict_torque(q, qd, qdd), atol=1e-9)
    dart = DartPlant(robot)
    np.testing.assert_allclose(dart.inverse_dynamics(q[0], qd[0], qdd[0]), robot.inverse_dynamics(q[0], qd[0], qdd[0]),
                               atol=1e-9)
    # The whole joint-7 body (link 7 + hand + fingers + tool) sits on link 7.
    links = {ln["name"]: ln for ln in json.loads(path.read_text())["links"]}
    assert links["panda_hand"]["mass"] == 0 and links["panda_hand"]["absorbed_into"] == "panda_link7"
    assert robot.total_mass == pytest.approx(
        hd.load_robot("panda").model_ff.inertias[1].mass + sum(p[0] for p in cons.body_params), abs=1e-9)


def test_a_dead_torque_channel_gives_bodies_outside_the_robots_bounds_and_identify_names_them(
        panda, mismatch_plant, noisy_mismatch_data):
    """With joint 4's torque 0 throughout, OLS returned bodies of negative mass with a centre
    of mass metres away and nothing said so. The bounds (``plausibility.PlausibilityBounds``) hold the truth: the
    simulated plant's own bodies (Franka's official inertials + a 0.5 kg tool, a set the nominal URDF differs
    from by 4x on link 2) are within them, and so are the fits of its clean data; the fits of the dead channel
    are not, body by body, in the fit record and on the command line."""
    from hybrid_dyn.identify.plausibility import implausible_bodies

    truth = nominal_body_parameters(mismatch_plant).reshape(panda.nv, -1)
    assert implausible_bodies(panda, truth) == []
    for method in ("ols", "consistent"):
        assert identify(noisy_mismatch_data, method, panda).fit["implausible"] == [], method
    q, qd, qdd, tau = (np.array(x) for x in noisy_mismatch_data)
    tau[:, 3] = 0.0
    ols = identify((q, qd, qdd, tau), "ols", panda)
    bad = ols.fit["implausible"]
    masses = [to_urdf_form(p)[0] for p in ols.body_params]
    assert min(masses) < 0  # the absurd fit the issue found, reproduced ...
    # ... and every body of negative mass is named, with its mass
    for j in np.flatnonzero(np.array(masses) < 0):
        assert any(b.startswith(f"body of panda_joint{j + 1}: mass {masses[j]:.3g} kg outside [0, ") for b in bad), bad
    assert ols.implausible_bodies() == bad  # recomputed from the parameters (a file read back is checked too)


def test_a_joint_that_never_moves_is_a_warning_with_its_range_and_the_condition_number(panda, tmp_path, capsys):
    """``identify`` once printed a condition number of 3e19 and no warning. Now a joint whose
    range of motion is under 5 degrees, and a condition number above 1e8, are warnings naming the joint; the
    same motion with every joint moving gives none."""
    from hybrid_dyn.cli import main

    q, qd, qdd = smooth_motion(panda, 600, seed=3)
    tau = panda.inverse_dynamics(q, qd, qdd)
    model = identify((q, qd, qdd, tau), "ols", panda)
    assert model.fit["warnings"] == [] and model.fit["condition_number"] < 1e8
    q[:, 3], qd[:, 3], qdd[:, 3] = q[0, 3], 0.0, 0.0
    still = identify((q, qd, qdd, panda.inverse_dynamics(q, qd, qdd)), "ols", panda)
    assert still.fit["range_of_motion_deg"][3] == 0.0
    assert still.fit["warnings"][0] == ("joint 4 (panda_joint4) moves 0 deg in the identification data, under the "
                                        "5 deg needed to identify it: its parameters are not determined by the data")
    assert still.fit["condition_number"] > 1e8 and "above 1e+08" in still.fit["warnings"][1]
    # On the command line, from a dataset of the still motion (the train split is what identify fits on).
    ds = _dataset(tmp_path / "ds", panda, q, qd, qdd, panda.inverse_dynamics(q, qd, qdd))
    assert main(["identify", "--data", str(ds), "--fit", "ols", "--splits", "train",
                 "--out", str(tmp_path / "p.json")]) == 0
    out = capsys.readouterr().out
    assert "warning: joint 4 (panda_joint4) moves 0 deg in the identification data, under the 5 deg" in out, out
    assert "warning: the base regressor of the identification data has condition number" in out


def _dataset(path, robot, q, qd, qdd, tau, hz=100.0):
    """A one-instance dataset (train split) of given samples, in the toolkit's format."""
    from hybrid_dyn.data.dataset import FIELD_UNITS, package_versions, write_instance, write_manifest

    fields = {"t": np.arange(len(q)) / hz, "q": q, "qd": qd, "qdd": qdd, "tau_m": tau}
    sha = write_instance(path / "instances" / "run.h5", fields)
    write_manifest(path, {"robot": robot.name, "scenario": "still", "seed": 0, "record_hz": hz, "config": {},
                          "fields": {k: FIELD_UNITS[k] for k in fields}, "packages": package_versions(),
                          "instances": [{"name": "run", "file": "instances/run.h5", "sha256": sha, "n_samples": len(q)}],
                          "splits": {"train": ["run"], "val": [], "test": []}})
    return path


@pytest.mark.slow
def test_sigmoid_friction_recovers_the_plants_gaz_law(panda, noisy_mismatch_data):
    gaz = panda.spec.friction("gaz2019")
    model = identify(noisy_mismatch_data, "sigmoid-friction", panda)
    assert model.physically_consistent
    v = np.linspace(-1.5, 1.5, 301)[:, None] * np.ones(panda.nv)
    err = np.abs(model.friction(v) - gaz(v)).max(axis=0)
    # Stated tolerance: 0.05 Nm over |qd| <= 1.5 rad/s (torque noise 0.05 Nm, 1500 samples).
    assert err.max() < 0.05, err
    # and it explains the data to the noise level
    assert np.max(model.fit["rmse_per_joint"]) < 0.06


@pytest.mark.slow
@pytest.mark.parametrize("method", list(IDENTIFICATION_METHODS))
def test_every_identification_method_fits_and_its_file_gives_the_same_torques(method, panda, noisy_mismatch_data,
                                                                            tmp_path):
    """Each registered method (a new one too): the model says which method made it, a method declared consistent
    gives physically consistent bodies, and its saved file, loaded, predicts the torques the model does."""
    model = identify(noisy_mismatch_data, method, panda)
    assert model.method == method
    if IDENTIFICATION_METHODS[method].consistent:
        assert model.physically_consistent
    law = {"linear": LinearFriction, "sigmoid": hd.description.GazFriction}[IDENTIFICATION_METHODS[method].friction]
    assert isinstance(model.friction, law)
    back = IdentifiedModel.load(model.save(tmp_path / f"{method}.json"))
    q, qd, qdd = random_states(panda, 5, seed=13)
    np.testing.assert_allclose(back.predict_torque(q, qd, qdd), model.predict_torque(q, qd, qdd), atol=1e-10)


def test_identified_model_file_roundtrip_and_errors(panda, noisy_mismatch_data, tmp_path):
    model = identify(noisy_mismatch_data, "wls", panda)
    path = model.save(tmp_path / "wls.json")
    back = IdentifiedModel.load(path)
    q, qd, qdd = random_states(panda, 5, seed=12)
    np.testing.assert_allclose(back.predict_torque(q, qd, qdd), model.predict_torque(q, qd, qdd), atol=1e-10)
    with pytest.raises(RobotDescriptionError, match="identified for robot 'panda'"):
        IdentifiedModel.load(path, robot=hd.load_robot("ur5"))
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(RobotDescriptionError, match="cannot read"):
        IdentifiedModel.load(bad)
    with pytest.raises(ValueError, match="unknown identification method"):
        identify(noisy_mismatch_data, "magic", panda)
    q, qd, qdd, tau = (np.array(x) for x in noisy_mismatch_data)
    tau[3, 2] = np.nan
    with pytest.raises(hd.InputError, match="NaN"):
        identify((q, qd, qdd, tau), "ols", panda)
    with pytest.raises(ValueError, match="base parameters"):
        identify((q[5:10], qd[5:10], qdd[5:10], tau[5:10]), "ols", panda)


def test_cli_identify_on_a_dataset(panda, tmp_path, capsys):
    from hybrid_dyn.cli import main
    from hybrid_dyn.data.synthetic import make_synthetic_dataset

    ds = make_synthetic_dataset(tmp_path / "ds", panda, n_instances=3, n_samples=300, tip_forces=False,
                                friction=panda.spec.friction("gaz2019"))
    out = tmp_path / "p.json"
    assert main(["identify", "--data", str(ds), "--fit", "ols", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "condition number" in text and "fit RMSE per joint" in text
    assert IdentifiedModel.load(out).method == "ols"
    assert main(["identify", "--data", str(tmp_path / "nope"), "--fit", "ols", "--out", str(out)]) == 2


# ------------------------------------------------------------------- excitation
@pytest.mark.slow
def test_excitation_design_respects_limits_and_improves_conditioning(panda):
    from hybrid_dyn.identify.excitation import ExcitationConfig, design_excitation

    cfg = ExcitationConfig(harmonics=3, n_grid=100, n_objective=15, max_iter=15)
    traj, report = design_excitation(panda, cfg)
    assert report["condition"] < report["condition_start"]
    t = np.linspace(0, traj.period, 4001)
    q, qd, qdd = traj.evaluate(t)
    dt = t[1] - t[0]
    # derivatives agree with finite differences of q (the formula is checked, not trusted)
    np.testing.assert_allclose(np.gradient(q, dt, axis=0)[2:-2], qd[2:-2], atol=1e-3)
    np.testing.assert_allclose(np.gradient(qd, dt, axis=0)[2:-2], qdd[2:-2], atol=1e-2)
    slack = 1.02  # the limits are enforced on a 100-point grid; between points a little more is possible
    assert (q >= panda.q_lower).all() and (q <= panda.q_upper).all()
    assert (np.abs(qd) <= slack * cfg.speed_fraction * np.array(panda.spec.max_velocity)).all()
    assert (np.abs(qdd) <= slack * cfg.accel_fraction * np.array(panda.spec.max_acceleration)).all()
    np.testing.assert_allclose(qd[0], 0, atol=1e-9)
    np.testing.assert_allclose(qdd[0], 0, atol=1e-9)
