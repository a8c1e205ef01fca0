"""The seed's network families in PyTorch: MLP, 1D-conv and LSTM.

Every network maps a standardized window x (B, L, F) to a standardized output
(B, n_out); the caller (``model.HybridModel``) owns the standardization and any
analytic part. Initialization follows the seed (Glorot uniform), with the
Keras defaults that "Glorot uniform" implied there for recurrent layers:
orthogonal recurrent weights, zero biases, forget-gate bias 1.

Which preset kind builds which class is declared with the kind (``learn/kinds.py``,
whose :func:`~hybrid_dyn.learn.kinds.build_net` is re-exported here); ``kind`` on
each class names it for the fast path (``learn/fastpath.py``).
"""
from __future__ import annotations

import torch
from torch import nn

from .kinds import build_net  # noqa: F401  (re-exported: the network of a kind, by its layer sizes)

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
    """Fully connected net on the current sample (the window's last row)."""

    kind = "mlp"

    def __init__(self, n_in: int, n_out: int, fc_layers: int, fc_units: int, activation: str, dropout: float = 0.0):
        super().__init__()
        self.head = fc_head(n_in, fc_layers, fc_units, n_out, activation, dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(x[:, -1])


class ConvNet(nn.Module):
    """One Conv1d front layer ('valid' padding, ReLU), flattened, then FC layers."""

    kind = "conv"

    def __init__(self, n_in: int, n_out: int, window: int, channels: int, kernel: int,
                 fc_layers: int, fc_units: int, activation: str, dropout: float = 0.0):
        super().__init__()
        self.conv = nn.Conv1d(n_in, channels, kernel)
        self.head = fc_head(channels * (window - kernel + 1), fc_layers, fc_units, n_out, activation, dropout)

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
