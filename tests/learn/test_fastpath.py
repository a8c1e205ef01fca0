"""The numba single-window kernels (learn/fastpath.py); each net kind against PyTorch: tests/learn/test_contracts.py."""
import numpy as np

from hybrid_dyn.learn.fastpath import _tanh



def test_tanh_through_exp_is_within_round_off():
    x = np.r_[np.linspace(-40.0, 40.0, 4001), np.geomspace(1e-300, 1.0, 50), -np.geomspace(1e-300, 1.0, 50),
              0.0, np.inf, -np.inf]
    got = np.array([_tanh(v) for v in x])
    np.testing.assert_allclose(got, np.tanh(x), rtol=0, atol=4e-16)
