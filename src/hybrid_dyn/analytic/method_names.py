"""The analytic estimators' one namespace, across their two registries: the tip-force methods
(``methods.TIP_FORCE_METHODS``) and the joint-torque models (``torque_models.TORQUE_MODELS``).

The residual priors and the model files name an estimator of either sort (``learn/priors.py``,
``learn/presets.py``); these two functions read both registries (the older spellings a model file may
hold too: each registry's ``aliases``). Everything else reads one registry directly.
"""
from __future__ import annotations

from ..deprecation import warn_renamed
from ..errors import UsageError
from .methods import TIP_FORCE_METHODS
from .torque_models import TORQUE_MODELS


def estimator_name(name, among=None, what: str = "analytic estimator", warn: bool = True) -> str:
    """The canonical name of estimator ``name`` (itself or an older spelling), one of ``among`` (default: all,
    the tip-force methods first).

    An older spelling warns (``DeprecatedNameWarning``) unless ``warn`` is False (a reader of an older file,
    which warns about the file once). An unknown name is refused with the canonical names it could
    have been."""
    among = tuple(TIP_FORCE_METHODS) + tuple(TORQUE_MODELS) if among is None else tuple(among)
    aliases = {**TIP_FORCE_METHODS.aliases, **TORQUE_MODELS.aliases}
    canonical = aliases.get(name, (name,))[0] if isinstance(name, str) else name
    if canonical not in among:
        older = (old for old, (new, _) in aliases.items() if new in among)
        raise UsageError(f"unknown {what} {name!r}; known: {', '.join(among)} "
                         f"(older spellings accepted: {', '.join(older)})")
    if warn and canonical != name:
        # The warning names the caller's sort (``what``), not the registry's, as it always has.
        warn_renamed(f"{what} spelling", name, canonical, stacklevel=3)
    return canonical


def residual_prior_names() -> tuple:
    """Every estimator a residual network may sit on now (a method registered later included): the
    torque models, then the tip-force methods, each in declaration order."""
    return tuple(m.name for registry in (TORQUE_MODELS, TIP_FORCE_METHODS) for m in registry.where(residual_prior=True))
