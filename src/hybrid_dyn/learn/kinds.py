"""Network kinds, each declared once with everything the toolkit needs to know about it.

A preset's ``kind`` (``learn/presets.py``) names one :class:`NetworkKind`. Its
declaration holds, together:

- ``build``: the torch modules of a model of this kind (``HybridModel`` holds them);
- ``fast``: their float64 single-call form (``learn/fastpath.py``), which the
  streaming estimator and ``TrainedModel.predict_window`` run;
- ``clips_gradients``: whether training clips the gradient norm
  (``TrainConfig.grad_clip``; the recurrent nets, whose gradients can explode);
- ``cost_rank``: its place in the bench's training queue (dearest per epoch first);
- ``search``: its hyperparameter search space (``learn/tune.py``);
- ``budget_steps``: the budgeted recipe's optimizer steps (``learn/recipes.py``);
- ``sequence`` and ``needs_front``: what a preset of it must give (a window longer
  than one sample; ``front_units``).

Every piece is required: a kind missing one is refused when it is declared
(:func:`register`), so no consumer falls back on a default for a kind it was
not told about. A new kind is one ``register(NetworkKind(...))`` call; see
``tests/learn/test_network_kinds.py`` for one declared and trained in a test.

Importing this module loads neither torch nor numba: the pieces import them
when they run.
"""
from __future__ import annotations

from collections.abc import Mapping
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


NETWORK_KINDS = Registry("network kind", ValueError, UsageError)  # name -> NetworkKind
KINDS = NETWORK_KINDS.keys()  # the kinds' names, a live view (a kind registered later is in it)
register = NETWORK_KINDS.register  # declare a kind: presets, training, the fast path, the bench and tuning know it
unregister = NETWORK_KINDS.unregister  # remove one (a test's toy)
network_kind = NETWORK_KINDS.lookup  # a kind by name; an unknown one is refused, naming the known ones


class _BudgetSteps(Mapping):
    """kind -> budgeted steps, read from the declarations (``recipes.BUDGET_STEPS``)."""

    def __getitem__(self, kind):
        return NETWORK_KINDS[kind].budget_steps

    def __iter__(self):
        return iter(NETWORK_KINDS)

    def __len__(self):
        return len(NETWORK_KINDS)

    def __repr__(self):
        return repr(dict(self))


BUDGET_STEPS = _BudgetSteps()


# --------------------------------------------------------------- what presets ask
def build_parts(preset, n_in: int, n_out: int, widths: dict) -> dict:
    """The modules of a model of ``preset``'s kind, by HybridModel attribute (every declared part)."""
    kind = network_kind(preset.kind)
    parts = kind.build(preset, n_in, n_out, widths)
    if set(parts) - set(kind.parts):
        raise ValueError(f"network kind {kind.name!r} built {sorted(parts)}; it declares {kind.parts}")
    return {name: parts.get(name) for name in kind.parts}


def build_net(kind: str, n_in: int, n_out: int, window: int, front_units: tuple, fc_layers: int,
              fc_units: int, activation: str, conv_kernel: int = 3, dropout: float = 0.0):
    """One network of a net kind from its layer sizes (a preset's plain net, or DeLaN's residual branch)."""
    k = network_kind(kind)
    if not k.is_net:
        raise ValueError(f"network kind {kind!r} is not a single network (its parts: {k.parts})")
    shape = SimpleNamespace(kind=kind, window=window, front_units=tuple(front_units), fc_layers=fc_layers,
                            fc_units=fc_units, activation=activation, conv_kernel=conv_kernel, dropout=dropout)
    return k.build(shape, n_in, n_out, {})["net"]


def fast_net_front(net):
    """The float64 front of a net built by a net kind (``net.kind``): window (L, F) -> the head's input."""
    return network_kind(net.kind).fast({"net": net})


def clips_gradients(preset) -> bool:
    """Whether training clips the gradient norm of ``preset``'s model (its kind's, or its residual branch's)."""
    if network_kind(preset.kind).clips_gradients:
        return True
    return preset.residual_kind is not None and network_kind(preset.residual_kind).clips_gradients


def cost_rank(preset) -> int:
    """The kind's epoch-cost rank, one higher with a residual branch (DeLaN + LSTM: the dearest)."""
    return network_kind(preset.kind).cost_rank + (1 if preset.residual_kind else 0)


def preset_problems(preset) -> list[str]:
    """What ``preset``'s kind refuses in its fields (``Preset.__post_init__`` raises them)."""
    if preset.kind not in NETWORK_KINDS:
        return [f"kind must be one of {', '.join(KINDS)}, got {preset.kind!r}"]
    kind = NETWORK_KINDS[preset.kind]
    out = []
    if not kind.sequence and preset.window != 1 and preset.residual_kind is None:
        out.append(f"{kind.name} sees the current sample only (window 1)")
    if kind.needs_front and not preset.front_units:
        out.append(f"{kind.name} needs front_units")
    if preset.residual_kind is not None:
        if preset.residual_kind not in NETWORK_KINDS or not NETWORK_KINDS[preset.residual_kind].is_net:
            nets = [k.name for k in NETWORK_KINDS.values() if k.is_net]
            out.append(f"residual_kind must be one of {', '.join(nets)}, got {preset.residual_kind!r}")
    reason = kind.check(preset) if kind.check is not None else None
    return out + ([reason] if reason else [])


# ------------------------------------------------------------ the built-in kinds
def single_net(make: Callable) -> Callable:
    """A net kind's builder from ``make(preset, n_in, n_out) -> module``: Glorot-initialized (the seed's
    init, ``nets.glorot_init``) and stamped with its kind (what FastNet looks up)."""
    def build(preset, n_in, n_out, widths):
        from .nets import glorot_init

        net = make(preset, n_in, n_out)
        glorot_init(net)
        net.kind = preset.kind
        return {"net": net}

    return build


def _mlp(p, n_in, n_out):
    from .nets import MLPNet

    return MLPNet(n_in, n_out, p.fc_layers, p.fc_units, p.activation, p.dropout)


def _conv(p, n_in, n_out):
    from .nets import ConvNet

    return ConvNet(n_in, n_out, p.window, p.front_units[0], p.conv_kernel, p.fc_layers, p.fc_units, p.activation,
                   p.dropout)


def _lstm(p, n_in, n_out):
    from .nets import LSTMNet

    return LSTMNet(n_in, n_out, tuple(p.front_units), p.fc_layers, p.fc_units, p.activation, p.dropout)


def _build_delan(p, n_in, n_out, widths):
    """DeLaN (``learn/delan.py``), its learned friction, and a residual branch of a net kind (ReLU)."""
    from .delan import DeepLagrangianNetwork, LearnedGazFriction

    nv = widths["q"]
    if list(p.inputs[:3]) != ["q", "qd", "qdd"] or n_out != nv:
        raise ValueError(f"preset {p.name!r}: DeLaN needs inputs q, qd, qdd first and joint-torque targets")
    delan = DeepLagrangianNetwork(nv, p.delan_hidden, p.delan_eps)
    friction = LearnedGazFriction(nv) if p.friction else None
    net = None
    if p.residual_kind:
        net = build_net(p.residual_kind, n_in, n_out, p.window, p.front_units, p.fc_layers, p.fc_units, "relu",
                        p.conv_kernel)
    return {"delan": delan, "friction": friction, "net": net}


def _fast(name: str) -> Callable:
    """A fast path of ``learn/fastpath.py`` by name, imported when first used (numba compiles then)."""
    def make(parts):
        from . import fastpath

        return getattr(fastpath, name)(parts)

    make.__name__ = name
    return make


# The seed's search space (its 3.3, with Keras Tuner): per kind, the front, then the FC layers.
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


def _search_lstm(trial, base) -> dict:
    n = trial.suggest_categorical("lstm_layers", SPACE["lstm_layers"])
    front = (trial.suggest_categorical("lstm_units", SPACE["lstm_units"]),) * n
    return {"front_units": front, **search_fc(trial, base)}


def _search_conv(trial, base) -> dict:
    return {"front_units": (trial.suggest_categorical("conv_units", SPACE["conv_units"]),), **search_fc(trial, base)}


def _search_delan(trial, base) -> dict:
    depth = trial.suggest_categorical("delan_layers", SPACE["delan_layers"])
    width = trial.suggest_categorical("delan_units", SPACE["delan_units"])
    return {"delan_hidden": (width,) * depth}


def _conv_window(preset) -> str | None:
    if preset.window < preset.conv_kernel:
        return f"window {preset.window} is shorter than the conv kernel"
    return None


# Budgeted steps: from the budget study (docs/models.md; now `hybrid-dyn study budget`) on seed-sim
# (80 instances) and paper-noext (40): the MLP's knee (the smallest budget whose doubling gains under
# 3 % on validation) on both; the others had knees on seed-sim (LSTM 2000, DeLaN 4000) but still gained
# 8-25 % per doubling on paper-noext, so they are set where the cost allows (conv 3-4 min a row, LSTM
# 4-7, DeLaN 6 on a loaded core) and are known not to have converged there. A DeLaN with a residual
# net counts as DeLaN. Cost ranks: measured on one thread on a default-profile scenario (144 k training
# windows, s per epoch): DeLaN 6.4 (with an LSTM residual 10.7), LSTMs 1.4-5.9, conv 1.1-1.6, MLPs
# 0.45-1.05; conv and MLP share a rank (the runner orders them by their front's width, conv first).
for _kind in (
    NetworkKind("mlp", "fully connected layers on the current sample", build=single_net(_mlp),
                fast=_fast("mlp_front"), clips_gradients=False, cost_rank=0, search=search_fc, budget_steps=8000,
                sequence=False, needs_front=False),
    NetworkKind("conv", "one Conv1d front layer ('valid', ReLU), flattened, then FC layers",
                build=single_net(_conv), fast=_fast("conv_front"), clips_gradients=False, cost_rank=0,
                search=_search_conv, budget_steps=16000, sequence=True, needs_front=True, check=_conv_window),
    NetworkKind("lstm", "stacked LSTM layers, the last step's state, then FC layers", build=single_net(_lstm),
                fast=_fast("lstm_front"), clips_gradients=True, cost_rank=1, search=_search_lstm,
                budget_steps=4000, sequence=True, needs_front=True),
    NetworkKind("delan", "Deep Lagrangian Network: H = L L^T + eps I, V(q); c, g by autograd",
                build=_build_delan, fast=_fast("delan_fast"), clips_gradients=False, cost_rank=2,
                search=_search_delan, budget_steps=16000, sequence=False, needs_front=False, parts=DELAN_PARTS),
):
    register(_kind)

__all__ = ["BUDGET_STEPS", "KINDS", "NETWORK_KINDS", "NetworkKind", "SPACE", "build_net", "build_parts",
           "clips_gradients", "cost_rank", "network_kind", "preset_problems", "register", "search_fc", "single_net",
           "unregister"]
