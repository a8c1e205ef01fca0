"""The numba single-window kernels (learn/fastpath.py) against PyTorch in float64, for every net kind."""
import numpy as np
import pytest
import torch

from hybrid_dyn.learn.fastpath import FastNet, _tanh
from hybrid_dyn.learn.nets import ConvNet, LSTMNet, MLPNet

WINDOW, N_IN, N_OUT = 10, 5, 3


@pytest.mark.parametrize("make", [
    lambda: MLPNet(N_IN, N_OUT, fc_layers=2, fc_units=8, activation="tanh"),
    lambda: ConvNet(N_IN, N_OUT, WINDOW, channels=4, kernel=3, fc_layers=1, fc_units=8, activation="relu"),
    lambda: LSTMNet(N_IN, N_OUT, units=(6, 4), fc_layers=2, fc_units=8, activation="relu"),  # two stacked layers
], ids=["mlp", "conv", "lstm"])
def test_fastnet_equals_torch_float64(make):
    torch.manual_seed(0)
    net = make().double().eval()
    with torch.no_grad():  # non-zero biases, so that every term is exercised
        for p in net.parameters():
            p.add_(0.3 * torch.randn_like(p))
    fast = FastNet(net)
    x = np.random.default_rng(1).normal(scale=2.0, size=(WINDOW, N_IN))
    with torch.no_grad():
        ref = net(torch.from_numpy(x)[None])[0].numpy()
    np.testing.assert_allclose(fast(x), ref, rtol=0, atol=1e-13)


def test_tanh_through_exp_is_within_round_off():
    x = np.r_[np.linspace(-40.0, 40.0, 4001), np.geomspace(1e-300, 1.0, 50), -np.geomspace(1e-300, 1.0, 50),
              0.0, np.inf, -np.inf]
    got = np.array([_tanh(v) for v in x])
    np.testing.assert_allclose(got, np.tanh(x), rtol=0, atol=4e-16)
