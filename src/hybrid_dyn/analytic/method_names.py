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

Older spellings (:data:`ALIASES`: ``basewrench`` and ``base_wrench``, ``torques``,
``momentum``, ``base_momentum``, ``kalman_fusion``, ``rnea-basewrench``) mean the same
estimator, and are accepted with a warning (``deprecation.DeprecatedNameWarning``) that names
the canonical one. Model files write the canonical names since format 3 (issue 30); an older
file's spellings are read by ``learn.trained_model.load_model``, which warns once per file instead.
"""
from __future__ import annotations

from ..errors import UsageError

ESTIMATORS = {
    "base-wrench": "tip_force",
    "torques-pinv": "tip_force",
    "momentum-observer": "tip_force",
    "base-momentum": "tip_force",
    "kalman-fusion": "tip_force",
    "rnea": "joint_torque",
    "rnea-bw": "joint_torque",
}
ALIASES = {
    "basewrench": "base-wrench",  # residual priors until issue 15
    "base_wrench": "base-wrench",  # TipForceEstimator methods until issue 15
    "torques": "torques-pinv",
    "momentum": "momentum-observer",
    "base_momentum": "base-momentum",
    "kalman_fusion": "kalman-fusion",
    "rnea-basewrench": "rnea-bw",
}


def estimator_name(name, among=None, what: str = "analytic estimator", warn: bool = True) -> str:
    """The canonical name of estimator ``name`` (itself or an alias), one of ``among`` (default: all).

    An alias warns (``DeprecatedNameWarning``) unless ``warn`` is False (a reader of an older file,
    which warns about the file once). An unknown name is refused with the canonical names it could
    have been."""
    among = tuple(ESTIMATORS) if among is None else tuple(among)
    canonical = ALIASES.get(name, name) if isinstance(name, str) else name
    if canonical not in among:
        raise UsageError(f"unknown {what} {name!r}; known: {', '.join(among)} "
                         f"(older spellings accepted: {', '.join(a for a, c in ALIASES.items() if c in among)})")
    if warn and canonical != name:
        from ..deprecation import warn_renamed

        warn_renamed(f"{what} spelling", name, canonical, stacklevel=3)
    return canonical
