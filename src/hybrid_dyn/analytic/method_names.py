"""One name per analytic estimator, used alike by the bench rows, the residual priors and
``TipForceEstimator(method=...)``.

The canonical names are the bench's (what users read in the reports):

============================  ===========  =================================================
name                          estimates    what
============================  ===========  =================================================
``base-wrench``               tip force    the base sensor's wrench minus the model's (needs qdd)
``torques-pinv``              tip force    F = pinv(J_v^T) (tau_J - ID(q, qd, qdd))
``momentum-observer``         tip force    the joint-torque momentum observer (no qdd)
``base-momentum``             tip force    the whole robot's momentum against the base sensor (no qdd)
``kalman-fusion``             tip force    both sensors fused by a Kalman filter
``rnea``                      tau_m        inverse dynamics (+ friction on an identified set)
``rnea-bw``                   tau_m        RNEA - J_v^T F, F from ``base-wrench``
============================  ===========  =================================================

The names are declared in one registry, :data:`ESTIMATOR_NAMES`: the two torque models here,
each tip-force method by its own declaration (``analytic/methods.register``). :data:`ESTIMATORS`
(name -> what it estimates) is read from it.

Older spellings (``ESTIMATOR_NAMES.alias``: ``basewrench`` and ``base_wrench``, ``torques``,
``momentum``, ``base_momentum``, ``kalman_fusion``, ``rnea-basewrench``; :data:`ALIASES` reads them)
mean the same estimator, and are accepted with a warning (``deprecation.DeprecatedNameWarning``)
that names the canonical one. Model files write the canonical names since format 3; an older
file's spellings are read by ``learn.trained_model.load_model``, which warns once per file instead.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..deprecation import warn_renamed
from ..errors import UsageError
from ..registry import Registry


@dataclass(frozen=True)
class EstimatorName:
    """An analytic estimator's one name, and what it estimates: "tip_force" [N] or "joint_torque" [Nm]
    (the bench task of its row). residual_prior: a residual network may sit on it (``learn/priors.py``)."""

    name: str
    estimates: str
    residual_prior: bool = False


ESTIMATOR_NAMES = Registry("analytic estimator", UsageError)
ESTIMATORS: dict[str, str] = {}  # name -> what it estimates, read from ESTIMATOR_NAMES (tip-force names first)


def _update_estimators(_changed=None) -> None:
    ESTIMATORS.clear()
    ESTIMATORS.update(sorted(((n, e.estimates) for n, e in ESTIMATOR_NAMES.items()), key=lambda x: x[1] != "tip_force"))


ESTIMATOR_NAMES.listen(_update_estimators, _update_estimators)
ESTIMATOR_NAMES.register(EstimatorName("rnea", "joint_torque", residual_prior=True))
ESTIMATOR_NAMES.register(EstimatorName("rnea-bw", "joint_torque", residual_prior=True))
ESTIMATOR_NAMES.alias("basewrench", "base-wrench", "the residual priors' old spelling")
ESTIMATOR_NAMES.alias("base_wrench", "base-wrench", "TipForceEstimator's old spelling")
ESTIMATOR_NAMES.alias("torques", "torques-pinv")
ESTIMATOR_NAMES.alias("momentum", "momentum-observer")
ESTIMATOR_NAMES.alias("base_momentum", "base-momentum")
ESTIMATOR_NAMES.alias("kalman_fusion", "kalman-fusion")
ESTIMATOR_NAMES.alias("rnea-basewrench", "rnea-bw")
ALIASES = {old: new for old, (new, _) in ESTIMATOR_NAMES.aliases.items()}  # older spelling -> the one name


def estimator_name(name, among=None, what: str = "analytic estimator", warn: bool = True) -> str:
    """The canonical name of estimator ``name`` (itself or an alias), one of ``among`` (default: all).

    An alias warns (``DeprecatedNameWarning``) unless ``warn`` is False (a reader of an older file,
    which warns about the file once). An unknown name is refused with the canonical names it could
    have been."""
    among = tuple(ESTIMATORS) if among is None else tuple(among)
    canonical = ESTIMATOR_NAMES.aliases.get(name, (name,))[0] if isinstance(name, str) else name
    if canonical not in among:
        older = (old for old, (new, _) in ESTIMATOR_NAMES.aliases.items() if new in among)
        raise UsageError(f"unknown {what} {name!r}; known: {', '.join(among)} "
                         f"(older spellings accepted: {', '.join(older)})")
    if warn and canonical != name:
        # The warning names the caller's sort (``what``), not the registry's, as it always has.
        warn_renamed(f"{what} spelling", name, canonical, stacklevel=3)
    return canonical


def residual_prior_names() -> tuple:
    """Every estimator a residual network may sit on now (a method registered later included)."""
    return tuple(e.name for e in ESTIMATOR_NAMES.where(residual_prior=True))
