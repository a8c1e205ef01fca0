"""Named model presets: the reference study's networks, the residual (hybrid) nets and DeLaN.

A :class:`Preset` is the complete description of a model family member: which
fields go in and come out, the input window's length, the network's layers and which
analytic part (if any) it corrects. Trained models store their preset in full,
so a model tuned by Optuna (a preset no registry names) loads like any other.

The reference study (Kruzic et al. 2021) fixes, in Table 1: the architecture type, whether
joint torques are inputs, the number and width of the fully connected layers
and the sequence length; conv and LSTM nets start with one 16-unit layer; the
optimized #10/#11 have two 32-unit LSTM layers. Its Table 3 torque nets give
only the type (and for the optimized LSTM: 2 x 32 LSTM, FC 2 x 8, tanh). What
the seed leaves unsaid is chosen here and documented in ``docs/models.md``:
conv kernel size 3 with 'valid' padding and no pooling (Keras' Conv1D
default), torque MLP/conv/LSTM widths as the tip-force #1/#4/#7, sequence
length 10 for the torque sequence nets.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

from ..analytic.methods import estimator_name, residual_prior_names  # (registers the tip-force methods: their names are read below)
from ..errors import UsageError
from ..plugins import load_plugins
from ..registry import Registry
from .kinds import NETWORK_KINDS, preset_problems

STATE = ["q", "qd", "qdd"]
TIP_INPUTS = ["base_wrench", "q", "qd", "qdd"]
TIP_INPUTS_TAU = TIP_INPUTS + ["tau_J"]

# How training fingerprints (and the keys of the prior caches) spell a prior: the spellings model files
# wrote until format 3. Frozen data, not names: every trained model and every cached training run is
# keyed by them, so a run of today finds the models trained before. Files write the estimators' names
# (:meth:`Preset.to_dict`); only these digests keep the old ones. A prior not listed is spelled by its name.
PRIOR_FINGERPRINT_SPELLING = {"rnea-bw": "rnea-basewrench", "base-wrench": "basewrench", "momentum-observer": "momentum"}


def prior_fingerprint_spelling(name: str) -> str:
    """The prior ``name`` (an estimator's name) as fingerprints and cache keys spell it."""
    return PRIOR_FINGERPRINT_SPELLING.get(name, name)


@dataclass(frozen=True)
class Preset:
    """A model architecture with its inputs and outputs.

    kind: the name of a declared network kind (``NETWORK_KINDS``; each says what it is).
    inputs / targets: dataset field names (see ``hybrid_dyn.data.FIELD_UNITS``).
    window: samples per input window (1 for MLP and DeLaN).
    front_units: units of each conv/LSTM front layer (conv uses the first only).
    fc_layers x fc_units: the fully connected layers after the front, then a
    linear output layer. activation: of the FC layers ("relu" or "tanh").
    dropout: probability of dropping an FC hidden unit in training (0: none;
    inference never drops).
    prior: the analytic part the network corrects (None: a plain network), by its estimator's name: a
    torque model of ``TORQUE_MODELS`` or a tip-force method of ``TIP_FORCE_METHODS`` declared with
    ``residual_prior=True`` (an older spelling, a registry alias, is read with a warning); a stateful
    method runs at dt = 1 / record_hz.
    raw_sensor: read the base wrench untared (a labelled reference row: what the
    sensor's per-run offset costs); by default every preset reads it tared, as
    every analytic row does (``learn/train.py``).
    delan_*: DeLaN's hidden layers for L(q) and V(q); friction: learn a Gaz
    sigmoid friction per joint; residual: add a residual network of the other
    fields (kind of the residual net: residual_kind, with its own input window).
    family: the bench family of its row (a name in ``bench.families.FAMILIES``; ``bench/learned_rows.py``),
    metadata of a declared preset, not of the model: files and fingerprints leave it out, equality ignores it.
    """

    name: str
    kind: str
    inputs: tuple
    targets: tuple
    window: int = 1
    front_units: tuple = ()
    fc_layers: int = 2
    fc_units: int = 16
    activation: str = "relu"
    dropout: float = 0.0
    conv_kernel: int = 3
    prior: str | None = None
    description: str = ""
    raw_sensor: bool = False
    # DeLaN only
    delan_hidden: tuple = (64, 64)
    delan_eps: float = 1e-3
    friction: bool = False
    residual_kind: str | None = None
    # Not part of the model (model files and fingerprints leave it out): the bench family of its row.
    family: str | None = field(default=None, compare=False)

    def __post_init__(self):
        if NETWORK_KINDS.missing([self.kind]):  # a plugin's kind (a model file of it) loads the plugins first
            raise ValueError(f"preset {self.name!r}: kind must be one of {tuple(NETWORK_KINDS)}, got {self.kind!r}")
        if self.prior is not None:  # one name per estimator; a saved model's older spelling is read as it
            if self.prior not in residual_prior_names():
                load_plugins()  # a plugin's method as the prior (a model file of it): declared once its plugin loads
            object.__setattr__(self, "prior",
                               estimator_name(self.prior, residual_prior_names(), f"prior of preset {self.name!r}"))
        if self.activation not in ("relu", "tanh"):
            raise ValueError(f"preset {self.name!r}: activation must be relu or tanh, got {self.activation!r}")
        if self.window < 1:
            raise ValueError(f"preset {self.name!r}: window must be >= 1")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"preset {self.name!r}: dropout must be in [0, 1), got {self.dropout}")
        problems = preset_problems(self)  # what the kind declares a preset of it must give
        if problems:
            raise ValueError(f"preset {self.name!r}: {'; '.join(problems)}")

    def to_dict(self) -> dict:
        """The preset as model files store it (JSON types; the prior by its canonical name; not its family)."""
        d = asdict(self)
        del d["family"]
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d

    def fingerprint_dict(self) -> dict:
        """The preset as training fingerprints hash it: :meth:`to_dict` with the prior in the spelling
        the fingerprints of every earlier run used (:data:`PRIOR_FINGERPRINT_SPELLING`)."""
        d = self.to_dict()
        if self.prior is not None:
            d["prior"] = prior_fingerprint_spelling(self.prior)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "Preset":
        """The preset of :meth:`to_dict`. An older spelling of the prior warns; ``load_model`` reads a
        model file's older spellings itself, with one warning per file."""
        d = dict(d)
        known = set(cls.__dataclass_fields__)
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"preset has unknown keys {sorted(unknown)}")
        for k in ("inputs", "targets", "front_units", "delan_hidden"):
            if k in d:
                d[k] = tuple(d[k])
        return cls(**d)

    def replace(self, **changes) -> "Preset":
        return replace(self, **changes)


def _tip(no, kind, torques, fc_units, window, front=(16,), activation="relu"):
    seq = "" if window == 1 else f", sequence length {window}"
    return Preset(
        name=f"seed-tip-{no}", kind=kind, inputs=tuple(TIP_INPUTS_TAU if torques else TIP_INPUTS),
        targets=("tip_force",), window=window, front_units=tuple(front) if kind != "mlp" else (),
        fc_layers=2, fc_units=fc_units, activation=activation, family="seed-net",
        description=f"seed Table 1 #{no}: {kind.upper()}, joint torques {'yes' if torques else 'no'}, "
                    f"FC 2 x {fc_units}{seq}",
    )


# name -> Preset: training, the CLI and the bench's rows (bench/learned_rows.py, which listens) read it.
# A declared preset names its bench family (a tuned preset, read from a model file, has none).
PRESETS = Registry("preset", UsageError,
                   check=lambda p: None if p.family is not None else "has no bench family: declare it with family=...")


for _preset in (
    _tip(1, "mlp", False, 32, 1),
    _tip(2, "mlp", True, 32, 1),
    _tip(3, "mlp", True, 16, 1),
    _tip(4, "conv", False, 16, 10),
    _tip(5, "conv", False, 16, 5),
    _tip(6, "conv", True, 16, 5),
    _tip(7, "lstm", False, 16, 10),
    _tip(8, "lstm", True, 16, 10),
    _tip(9, "lstm", True, 16, 5),
    _tip(10, "lstm", False, 16, 10, front=(32, 32)),
    _tip(11, "lstm", True, 8, 10, front=(32, 32)),
    # Reference row: #11 on the raw base sensor, its per-run offset left in.
    _tip(11, "lstm", True, 8, 10, front=(32, 32)).replace(
        name="seed-tip-11-raw", raw_sensor=True,
        description="seed Table 1 #11 on the raw (untared) base sensor: a reference row for the offset's cost"),
    Preset("seed-tau-mlp", "mlp", tuple(STATE), ("tau_m",), fc_units=32,
           family="seed-net", description="seed Table 3 MLP (widths as Table 1 #1)"),
    Preset("seed-tau-conv", "conv", tuple(STATE), ("tau_m",), window=10, front_units=(16,),
           family="seed-net", description="seed Table 3 conv (widths as Table 1 #4)"),
    Preset("seed-tau-lstm", "lstm", tuple(STATE), ("tau_m",), window=10, front_units=(16,),
           family="seed-net", description="seed Table 3 LSTM (widths as Table 1 #7)"),
    Preset("seed-tau-lstm-opt", "lstm", tuple(STATE), ("tau_m",), window=10, front_units=(32, 32),
           fc_units=8, activation="tanh", family="seed-net",
           description="seed Table 3 #10: optimized LSTM, 2 x 32, FC 2 x 8, tanh"),
    # Not from the seed: for small real-robot sets (a handful of trajectories), width plus dropout
    # generalise to unseen trajectories better than the reference study's 2 x 32 (a search on the validation
    # split of the three real sets; docs/models.md).
    Preset("tau-mlp-wide", "mlp", tuple(STATE), ("tau_m",), fc_units=128, dropout=0.2,
           family="learned",
           description="regularised MLP for small real-robot sets: FC 2 x 128, dropout 0.2 (not from the seed)"),
    # Residual (hybrid) models: a small LSTM learns what the analytic part misses.
    Preset("residual-rnea", "lstm", tuple(STATE), ("tau_m",), window=10, front_units=(32,),
           prior="rnea", family="residual", description="tau = RNEA_nominal(q, qd, qdd) + LSTM(window of q, qd, qdd)"),
    Preset("residual-rnea-bw", "lstm", tuple(STATE + ["base_wrench"]), ("tau_m",), window=10,
           front_units=(32,), prior="rnea-bw",
           family="residual", description="tau = RNEA - J_v^T F_basewrench + LSTM(window of q, qd, qdd, base_wrench)"),
    Preset("residual-basewrench", "lstm", tuple(TIP_INPUTS), ("tip_force",), window=10, front_units=(32,),
           prior="base-wrench", family="residual",
           description="F = base-wrench method + LSTM(window of base_wrench, q, qd, qdd)"),
    Preset("residual-momentum", "lstm", tuple(STATE + ["tau_J"]), ("tip_force",), window=10,
           front_units=(32,), prior="momentum-observer",
           family="residual", description="F = momentum observer(q, qd, tau_J) + LSTM(window of q, qd, qdd, tau_J)"),
    Preset("residual-base-momentum", "lstm", tuple(TIP_INPUTS), ("tip_force",), window=10, front_units=(32,),
           prior="base-momentum",
           family="residual",
           description="F = base momentum observer(q, qd, tared base_wrench) + LSTM(window of base_wrench, q, qd, qdd)"),
    # DeLaN (Lutter et al. 2019): tau = H qdd + c + g (+ friction) (+ residual).
    Preset("delan", "delan", tuple(STATE), ("tau_m",), activation="tanh",
           family="delan", description="DeLaN: H = L L^T + eps I, V(q); c, g by autograd"),
    Preset("delan-friction", "delan", tuple(STATE), ("tau_m",), activation="tanh", friction=True,
           family="delan", description="DeLaN + learned Gaz sigmoid friction"),
    Preset("delan-residual", "delan", tuple(STATE), ("tau_m",), window=10, activation="tanh", friction=True,
           residual_kind="lstm", front_units=(32,),
           family="residual", description="DeLaN + learned friction + LSTM residual on the window of q, qd, qdd"),
):
    PRESETS.register(_preset)
