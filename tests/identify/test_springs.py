"""A declared joint spring (robots/baxter.toml: the shoulder's gravity-assist spring), identified.

The torques are built here from the nominal model plus a spring and friction of known values, so the
fit has an exact answer to recover.
"""
import json

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.description import RobotDescriptionError
from hybrid_dyn.identify import IdentifiedModel, identify

from helpers.states import random_states

K_S1 = [-12.0, 6.0, 4.0]  # the spring law's k_lin [Nm/rad], k_sin, k_cos [Nm] to recover
FV, FO = 0.8, 0.3  # viscous [Nm s/rad] and offset [Nm] friction on every joint
NOISE = 0.05  # Nm: a torque sensor's noise (exact torques leave the consistent fit's weights degenerate)


@pytest.fixture(scope="module")
def baxter_data():
    robot = hd.load_robot("baxter")
    q, qd, qdd = random_states(robot, 600, seed=7)
    spring = np.zeros_like(q)
    # s1 is the second joint of the chain; the law written out here, not through extra_terms
    spring[:, 1] = K_S1[0] * q[:, 1] + K_S1[1] * np.sin(q[:, 1]) + K_S1[2] * np.cos(q[:, 1])
    tau = robot.inverse_dynamics(q, qd, qdd) + FV * qd + FO + spring
    tau += np.random.default_rng(1).normal(0.0, NOISE, tau.shape)
    return robot, (q, qd, qdd, tau)


@pytest.mark.parametrize("method", ["ols", "consistent"])
def test_the_spring_is_recovered_and_predicts(baxter_data, method):
    robot, (q, qd, qdd, tau) = baxter_data
    model = identify((q, qd, qdd, tau), method, robot)
    assert set(model.springs) == {"left_s1"}
    # The linear term is the spring's alone; its first harmonic trades a little with the distal bodies'
    # gravity on s1 (both are harmonics of q_s1), so the law is checked as a torque curve over s1's range.
    assert model.springs["left_s1"][0] == pytest.approx(K_S1[0], abs=0.1)
    qs1 = np.linspace(robot.q_lower[1], robot.q_upper[1], 50)
    law = lambda k: k[0] * qs1 + k[1] * np.sin(qs1) + k[2] * np.cos(qs1)  # noqa: E731
    assert np.abs(law(model.springs["left_s1"]) - law(K_S1)).max() < 0.5
    qt, qdt, qddt = random_states(robot, 100, seed=8)
    truth = robot.inverse_dynamics(qt, qdt, qddt) + FV * qdt + FO
    truth[:, 1] += K_S1[0] * qt[:, 1] + K_S1[1] * np.sin(qt[:, 1]) + K_S1[2] * np.cos(qt[:, 1])
    np.testing.assert_allclose(model.predict_torque(qt, qdt, qddt), truth, atol=4 * NOISE)


def test_without_the_declared_term_the_shoulder_misses(baxter_data, tmp_path):
    """The same data on a Baxter that declares no spring: s1 is left with the spring's torque."""
    robot, (q, qd, qdd, tau) = baxter_data
    text = robot.spec.source.read_text().replace('springs = ["left_s1"]', "springs = []")
    (tmp_path / "baxter.toml").write_text(text)
    bare = hd.load_robot(str(tmp_path / "baxter.toml"))
    model = identify((q, qd, qdd, tau), "ols", bare)
    err = np.sqrt(np.mean((model.predict_torque(q, qd, qdd) - tau) ** 2, axis=0))
    assert model.springs == {} and err[1] > 1.0 and np.delete(err, 1).max() < 0.5


def test_the_springs_survive_the_file_and_a_bad_section_is_named(baxter_data, tmp_path):
    robot, data = baxter_data
    model = identify(data, "ols", robot)
    path = model.save(tmp_path / "baxter.json")
    back = IdentifiedModel.load(path, robot)
    assert back.springs == model.springs
    q, qd, qdd, _ = data
    np.testing.assert_allclose(back.predict_torque(q[:5], qd[:5], qdd[:5]), model.predict_torque(q[:5], qd[:5], qdd[:5]))
    doc = json.loads(path.read_text())
    doc["springs"]["coefficients"] = {"left_elbow": [3.0, 0.0, 0.0]}
    path.write_text(json.dumps(doc))
    with pytest.raises(RobotDescriptionError, match="springs section"):
        IdentifiedModel.load(path, robot)


def test_the_sigmoid_fit_keeps_a_spring_that_predicts(baxter_data):
    """The sigmoid friction fit takes the consistent fit's spring law (the least-squares one pairs with
    whatever unphysical bodies least squares chose: on the real Baxter log it left s1 15 Nm off), and
    its torques stay right on s1."""
    robot, (q, qd, qdd, tau) = baxter_data
    model = identify((q, qd, qdd, tau), "sigmoid-friction", robot)
    consistent = identify((q, qd, qdd, tau), "consistent", robot)
    np.testing.assert_allclose(model.springs["left_s1"], consistent.springs["left_s1"], rtol=1e-6)
    err = np.sqrt(np.mean((model.predict_torque(q, qd, qdd) - tau) ** 2, axis=0))
    # Viscous friction is not a sigmoid, so every joint keeps some error; s1 keeps no more than the others.
    assert err[1] < 2 * np.delete(err, 1).max() + 0.1, err
