"""What a network kind is (:class:`NetworkKind`) and its registry, :data:`NETWORK_KINDS`.

The bottom of ``learn/``: it imports no network module, so every module that declares a kind
(``nets.py``: mlp, conv, lstm; ``delan.py``: delan) imports it, and nothing circles. The catalogue,
``learn/kinds.py``, imports the declaring modules. A kind missing a piece (``_PIECES``) is refused when
it is declared, so no consumer falls back on a default. Importing this module loads neither torch nor
numba. A new kind: ``docs/extending.md``.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Callable

from ..errors import UsageError
from ..registry import Registry

# The parts a model may hold, by HybridModel attribute: a plain net, or DeLaN's structured model.
NET_PARTS = ("net",)
DELAN_PARTS = ("delan", "friction", "net")

_PIECES = {  # field -> what it is, for the error that names a missing one
    "build": "the builder: (preset, n_in, n_out, widths) -> {part: module}",
    "fast": "the float64 single-call path: {part: module} -> evaluator",
    "clips_gradients": "whether training clips its gradient norm (True/False)",
    "cost_rank": "its epoch-cost rank in the bench's training queue (an int, dearer higher)",
    "search": "its search space: (optuna trial, base preset) -> preset changes",
    "budget_steps": "the budgeted recipe's optimizer steps (an int > 0)",
    "sequence": "whether it reads a window of samples (False: the current sample only)",
    "needs_front": "whether a preset must give front_units",
}


@dataclass(frozen=True)
class NetworkKind:
    """One network kind (see the module docstring for each piece).

    build(preset, n_in, n_out, widths) -> dict: the modules, by HybridModel attribute (``parts``),
    built in that order (the order torch's random draws follow); n_in / n_out: input and output
    columns; widths: field -> columns. A net kind (``parts == ("net",)``) returns one module with
    a ``head`` (``nets.fc_head``: FastNet evaluates it, a residual's output layer starts at zero).
    fast(parts) -> callable: for a net kind, the float64 front: a standardized window (L, F) ->
    the head's input (FastNet adds the head); for DeLaN, (q, qd, qdd) -> tau [Nm].
    check(preset) -> str | None: an optional rule of this kind on a preset's fields (the reason
    it is refused, or None).
    """

    name: str
    description: str = ""
    build: Callable | None = None
    fast: Callable | None = None
    clips_gradients: bool | None = None
    cost_rank: int | None = None
    search: Callable | None = None
    budget_steps: int | None = None
    sequence: bool | None = None
    needs_front: bool | None = None
    parts: tuple = NET_PARTS
    check: Callable | None = None

    def __post_init__(self):
        missing = [f"{k} ({what})" for k, what in _PIECES.items() if getattr(self, k) is None]
        if missing:
            raise ValueError(f"network kind {self.name!r} lacks: {'; '.join(missing)}")
        bad = [k for k in ("build", "fast", "search") if not callable(getattr(self, k))]
        bad += [k for k in ("clips_gradients", "sequence", "needs_front") if not isinstance(getattr(self, k), bool)]
        bad += [k for k in ("cost_rank",) if not isinstance(self.cost_rank, int) or isinstance(self.cost_rank, bool)]
        if not isinstance(self.budget_steps, int) or isinstance(self.budget_steps, bool) or self.budget_steps < 1:
            bad.append("budget_steps")
        if bad:
            raise ValueError(f"network kind {self.name!r}: {', '.join(f'{k} must be {_PIECES[k]}' for k in bad)}")
        if "net" not in self.parts:
            raise ValueError(f"network kind {self.name!r}: parts must include 'net' (a residual branch), got {self.parts}")

    @property
    def is_net(self) -> bool:
        """Whether the kind is one network with a head (a residual branch may be of this kind)."""
        return tuple(self.parts) == NET_PARTS


NETWORK_KINDS = Registry("network kind", ValueError, UsageError)  # name -> NetworkKind; catalogue: learn/kinds.py


# --------------------------------------------------------------- what presets ask
def build_parts(preset, n_in: int, n_out: int, widths: dict) -> dict:
    """The modules of a model of ``preset``'s kind, by HybridModel attribute (every declared part)."""
    kind = NETWORK_KINDS.lookup(preset.kind)
    parts = kind.build(preset, n_in, n_out, widths)
    if set(parts) - set(kind.parts):
        raise ValueError(f"network kind {kind.name!r} built {sorted(parts)}; it declares {kind.parts}")
    return {name: parts.get(name) for name in kind.parts}


def build_net(kind: str, n_in: int, n_out: int, window: int, front_units: tuple, fc_layers: int,
              fc_units: int, activation: str, conv_kernel: int = 3, dropout: float = 0.0):
    """One network of a net kind from its layer sizes (a preset's plain net, or DeLaN's residual branch)."""
    k = NETWORK_KINDS.lookup(kind)
    if not k.is_net:
        raise ValueError(f"network kind {kind!r} is not a single network (its parts: {k.parts})")
    shape = SimpleNamespace(kind=kind, window=window, front_units=tuple(front_units), fc_layers=fc_layers,
                            fc_units=fc_units, activation=activation, conv_kernel=conv_kernel, dropout=dropout)
    return k.build(shape, n_in, n_out, {})["net"]


def fast_net_front(net):
    """The float64 front of a net built by a net kind (``net.kind``): window (L, F) -> the head's input."""
    return NETWORK_KINDS.lookup(net.kind).fast({"net": net})


def clips_gradients(preset) -> bool:
    """Whether training clips the gradient norm of ``preset``'s model (its kind's, or its residual branch's)."""
    if NETWORK_KINDS.lookup(preset.kind).clips_gradients:
        return True
    return preset.residual_kind is not None and NETWORK_KINDS.lookup(preset.residual_kind).clips_gradients


def cost_rank(preset) -> int:
    """The kind's epoch-cost rank, one higher with a residual branch (DeLaN + LSTM: the dearest)."""
    return NETWORK_KINDS.lookup(preset.kind).cost_rank + (1 if preset.residual_kind else 0)


def preset_problems(preset) -> list[str]:
    """What ``preset``'s kind refuses in its fields (``Preset.__post_init__`` raises them)."""
    if NETWORK_KINDS.missing([preset.kind]):
        return [f"kind must be one of {', '.join(NETWORK_KINDS)}, got {preset.kind!r}"]
    kind = NETWORK_KINDS[preset.kind]
    out = []
    if not kind.sequence and preset.window != 1 and preset.residual_kind is None:
        out.append(f"{kind.name} sees the current sample only (window 1)")
    if kind.needs_front and not preset.front_units:
        out.append(f"{kind.name} needs front_units")
    if preset.residual_kind is not None:
        if NETWORK_KINDS.missing([preset.residual_kind]) or not NETWORK_KINDS[preset.residual_kind].is_net:
            nets = [k.name for k in NETWORK_KINDS.values() if k.is_net]
            out.append(f"residual_kind must be one of {', '.join(nets)}, got {preset.residual_kind!r}")
    reason = kind.check(preset) if kind.check is not None else None
    return out + ([reason] if reason else [])


# ------------------------------------------------------------ the search space
# The reference study's search space (its 3.3, with Keras Tuner): per kind, the front, then the FC layers. One table,
# as the seed gives it; each kind's ``search`` draws its part (a new kind may keep its values beside it).
SPACE = {
    "lstm_layers": (1, 2, 3),
    "lstm_units": (8, 16, 32, 64),
    "conv_units": (8, 16, 32, 64),
    "fc_layers": (1, 2, 3),
    "fc_units": (8, 16, 32, 64),
    "activation": ("relu", "tanh"),
    "delan_layers": (1, 2, 3),
    "delan_units": (32, 64, 128),
}


def search_fc(trial, base) -> dict:
    """The FC head's part of a search: its depth, width and activation."""
    return {"fc_layers": trial.suggest_categorical("fc_layers", SPACE["fc_layers"]),
            "fc_units": trial.suggest_categorical("fc_units", SPACE["fc_units"]),
            "activation": trial.suggest_categorical("activation", SPACE["activation"])}


__all__ = ["DELAN_PARTS", "NETWORK_KINDS", "NET_PARTS", "NetworkKind", "SPACE", "build_net", "build_parts",
           "clips_gradients", "cost_rank", "fast_net_front", "preset_problems", "search_fc"]
