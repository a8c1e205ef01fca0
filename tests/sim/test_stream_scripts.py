"""The scripts that ran hand-written loops (checks/, examples/, benchmarks/) run on the one stream
simulator (``sim.stream``) and tell the estimator what their encoders are."""
import importlib.util

import numpy as np
import pytest

from hybrid_dyn.estimator import TipForceEstimator
from hybrid_dyn.sim.sensors import HardwareSensors

from helpers import REPO


def load_script(folder: str, name: str):
    """FOLDER/NAME.py as a module (the scripts are not part of the package)."""
    spec = importlib.util.spec_from_file_location(name, REPO / folder / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def told(monkeypatch):
    """The encoder_resolution each analytic estimator a script builds is given."""
    seen = []
    original = TipForceEstimator.analytic.__func__

    def analytic(cls, robot="panda", method="base-wrench", params=None, **config):
        seen.append(config.get("encoder_resolution", "not given"))
        return original(cls, robot, method, params, **config)

    monkeypatch.setattr(TipForceEstimator, "analytic", classmethod(analytic))
    return seen


def test_the_stream_check_keeps_issue_27s_sensors_and_says_the_encoders_are_exact(told, capsys):
    check = load_script("checks", "tip_force_stream")
    s = check.stream_config(12.0, 0.05, 0.0).sensors
    assert (s.encoder.resolution, s.encoder.velocity, s.tau_J_noise, s.clock.jitter) == (0.0, "exact", 0.0, 0.0)
    b = s.base
    assert (b.force_noise, b.force_bias, b.torque_bias, b.force_drift, b.torque_drift, b.delay) == (0.05, 2.0, 0.1, 0, 0, 0)
    assert b.torque_noise == pytest.approx(0.0025)
    quantized = check.stream_config(12.0, 0.05, 1e-5).sensors.encoder
    assert (quantized.resolution, quantized.velocity) == (1e-5, "difference")
    check.main(["--streams", "1", "--seconds", "0.8"])
    assert told == [0.0] * len(check.BASE_ONLY)  # its joint-state filter is for quantized encoders
    assert "encoder resolution 0 rad" in capsys.readouterr().out


def test_the_example_reads_hardware_sensors_and_tells_the_estimator_their_resolution(told, capsys):
    example = load_script("examples", "control_loop")
    example.main(["--seconds", "3.5", "--method", "base-momentum"])  # into the push (from 3 s)
    assert told == [1e-5]  # the Panda's encoders, from its description
    out = capsys.readouterr().out
    assert "latency per call" in out and "nan" not in out


def test_the_latency_benchmarks_stream_is_read_by_the_hardware_defaults(panda):
    bench = load_script("benchmarks", "estimator_latency")
    t, q, qd, w, tau = bench.stream(panda, 400)
    assert HardwareSensors().encoder.resolution == "auto"  # the description's, 1e-5 rad on the Panda
    np.testing.assert_allclose(q / 1e-5, np.round(q / 1e-5), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(qd[1:], np.diff(q, axis=0) / 1e-3)
    np.testing.assert_allclose(np.diff(t), 1e-3, atol=1e-12)
    assert w.shape == (400, 6) and tau.shape == (400, 7)
