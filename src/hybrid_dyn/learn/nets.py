"""The reference study's network families in PyTorch: MLP, 1D-conv and LSTM, and their three network kinds.

Every network maps a standardized input window x (B, L, F) to a standardized output
(B, n_out); the caller (``model.HybridModel``) owns the standardization and any
analytic part. Initialization follows the seed (Glorot uniform), with the
Keras defaults that "Glorot uniform" implied there for recurrent layers:
orthogonal recurrent weights, zero biases, forget-gate bias 1.

The kinds ``mlp``, ``conv`` and ``lstm`` are declared at the end of this module, in the kind
registry (``learn/kind_registry.py``, whose :func:`~hybrid_dyn.learn.kind_registry.build_net` is
re-exported here); ``kind`` on each class names it for the fast path (``learn/fastpath.py``).
"""
from __future__ import annotations

from typing import Callable

import torch
from torch import nn

from .kind_registry import NETWORK_KINDS, SPACE, NetworkKind, search_fc
from .kind_registry import build_net  # noqa: F401  (re-exported: the network of a kind, by its layer sizes)

ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh}


def fc_head(n_in: int, n_layers: int, n_units: int, n_out: int, activation: str,
            dropout: float = 0.0) -> nn.Sequential:
    """n_layers fully connected layers of n_units with ``activation`` (and dropout
    after each when dropout > 0: active in training only), then a linear output."""
    layers: list[nn.Module] = []
    for _ in range(n_layers):
        layers += [nn.Linear(n_in, n_units), ACTIVATIONS[activation]()]
        if dropout > 0:
            layers.append(nn.Dropout(dropout))
        n_in = n_units
    layers.append(nn.Linear(n_in, n_out))
    return nn.Sequential(*layers)


class MLPNet(nn.Module):
    """Fully connected net on the current sample (the input window's last row)."""

    kind = "mlp"

    def __init__(self, n_in: int, n_out: int, fc_layers: int, fc_units: int, activation: str, dropout: float = 0.0):
        super().__init__()
        self.head = fc_head(n_in, fc_layers, fc_units, n_out, activation, dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(x[:, -1])


class ConvNet(nn.Module):
    """One Conv1d front layer ('valid' padding, ReLU), flattened, then FC layers."""

    kind = "conv"

    def __init__(self, n_in: int, n_out: int, input_window: int, channels: int, kernel: int,
                 fc_layers: int, fc_units: int, activation: str, dropout: float = 0.0):
        super().__init__()
        self.conv = nn.Conv1d(n_in, channels, kernel)
        self.head = fc_head(channels * (input_window - kernel + 1), fc_layers, fc_units, n_out, activation, dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = torch.relu(self.conv(x.transpose(1, 2)))  # (B, C, L - k + 1)
        return self.head(h.flatten(1))


class LSTMNet(nn.Module):
    """Stacked LSTM layers (units per layer), the last step's state, then FC layers."""

    kind = "lstm"

    def __init__(self, n_in: int, n_out: int, units: tuple, fc_layers: int, fc_units: int, activation: str,
                 dropout: float = 0.0):
        super().__init__()
        self.lstms = nn.ModuleList()
        for u in units:
            self.lstms.append(nn.LSTM(n_in, u, batch_first=True))
            n_in = u
        self.head = fc_head(n_in, fc_layers, fc_units, n_out, activation, dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        for lstm in self.lstms:
            x, _ = lstm(x)
        return self.head(x[:, -1])


def glorot_init(module: nn.Module) -> None:
    """Glorot-uniform weights and zero biases; LSTMs as Keras does it."""
    for m in module.modules():
        if isinstance(m, (nn.Linear, nn.Conv1d)):
            nn.init.xavier_uniform_(m.weight)
            nn.init.zeros_(m.bias)
        elif isinstance(m, nn.LSTM):
            for name, p in m.named_parameters():
                if name.startswith("weight_ih"):
                    for gate in p.data.chunk(4, 0):  # per gate, as Keras' kernel of 4 blocks
                        nn.init.xavier_uniform_(gate)
                elif name.startswith("weight_hh"):
                    for gate in p.data.chunk(4, 0):
                        nn.init.orthogonal_(gate)
                elif name.startswith("bias_ih"):
                    nn.init.zeros_(p)
                    h = p.shape[0] // 4
                    p.data[h:2 * h] = 1.0  # forget gate (PyTorch order i, f, g, o)
                elif name.startswith("bias_hh"):
                    nn.init.zeros_(p)


# ------------------------------------------------------------ the three kinds
def single_net(make: Callable) -> Callable:
    """A net kind's builder from ``make(preset, n_in, n_out) -> module``: Glorot-initialized (the reference study's
    init, :func:`glorot_init`) and stamped with its kind (what FastNet looks up)."""
    def build(preset, n_in, n_out, widths):
        net = make(preset, n_in, n_out)
        glorot_init(net)
        net.kind = preset.kind
        return {"net": net}

    return build


def fast_path(name: str) -> Callable:
    """A fast path of ``learn/fastpath.py`` by name, imported when first used (numba compiles then)."""
    def make(parts):
        from . import fastpath

        return getattr(fastpath, name)(parts)

    make.__name__ = name
    return make


def _mlp(p, n_in, n_out):
    return MLPNet(n_in, n_out, p.fc_layers, p.fc_units, p.activation, p.dropout)


def _conv(p, n_in, n_out):
    return ConvNet(n_in, n_out, p.window, p.front_units[0], p.conv_kernel, p.fc_layers, p.fc_units, p.activation,
                   p.dropout)


def _lstm(p, n_in, n_out):
    return LSTMNet(n_in, n_out, tuple(p.front_units), p.fc_layers, p.fc_units, p.activation, p.dropout)


def _search_lstm(trial, base) -> dict:
    n = trial.suggest_categorical("lstm_layers", SPACE["lstm_layers"])
    front = (trial.suggest_categorical("lstm_units", SPACE["lstm_units"]),) * n
    return {"front_units": front, **search_fc(trial, base)}


def _search_conv(trial, base) -> dict:
    return {"front_units": (trial.suggest_categorical("conv_units", SPACE["conv_units"]),), **search_fc(trial, base)}


def _conv_window(preset) -> str | None:
    if preset.window < preset.conv_kernel:
        return f"input window {preset.window} is shorter than the conv kernel"
    return None


# Budgeted steps: from the budget study (docs/models.md; now `hybrid-dyn study budget`) on seed-sim
# (80 instances) and paper-noext (40): the MLP's knee (the smallest budget whose doubling gains under
# 3 % on validation) on both; the others had knees on seed-sim (LSTM 2000, DeLaN 4000) but still gained
# 8-25 % per doubling on paper-noext, so they are set where the cost allows (conv 3-4 min a row, LSTM
# 4-7, DeLaN 6 on a loaded core: ``delan.py``) and are known not to have converged there. Cost ranks:
# measured on one thread on a default-profile scenario (144 k training input windows, s per epoch): DeLaN 6.4
# (with an LSTM residual 10.7), LSTMs 1.4-5.9, conv 1.1-1.6, MLPs 0.45-1.05; conv and MLP share a rank
# (the runner orders them by their front's width, conv first).
NETWORK_KINDS.register(NetworkKind("mlp", "fully connected layers on the current sample", build=single_net(_mlp),
                     fast=fast_path("mlp_front"), clips_gradients=False, cost_rank=0, search=search_fc,
                     budget_steps=8000, sequence=False, needs_front=False))
NETWORK_KINDS.register(NetworkKind("conv", "one Conv1d front layer ('valid', ReLU), flattened, then FC layers",
                     build=single_net(_conv), fast=fast_path("conv_front"), clips_gradients=False, cost_rank=0,
                     search=_search_conv, budget_steps=16000, sequence=True, needs_front=True, check=_conv_window))
NETWORK_KINDS.register(NetworkKind("lstm", "stacked LSTM layers, the last step's state, then FC layers",
                     build=single_net(_lstm), fast=fast_path("lstm_front"), clips_gradients=True, cost_rank=1,
                     search=_search_lstm, budget_steps=4000, sequence=True, needs_front=True))
