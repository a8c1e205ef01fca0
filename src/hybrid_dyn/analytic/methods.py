"""The catalogue of the analytic estimators: what a consumer imports.

Importing it declares the built-in tip-force methods in :data:`TIP_FORCE_METHODS`
(``method_declaration.py``, which says what a method is), each by its own module, in this order (the
bench's row order). A consumer imports the registry from here; a new method's module adds one line here
(or is imported by its own package), and imports from ``method_declaration`` itself (importing this
catalogue would make an import circle).

It holds, besides: the default method (:data:`DEFAULT_METHOD`) and the estimators' one namespace
across their two registries, the tip-force methods and the joint-torque models
(``torque_models.TORQUE_MODELS``): :func:`estimator_name` and :func:`residual_prior_names`, read by
the residual priors and the model files (``learn/priors.py``, ``learn/presets.py``), which name an
estimator of either sort (the older spellings a model file may hold too: each registry's ``aliases``);
everything else reads one registry directly.

Built from the registry: ``TipForceEstimator.analytic(robot, method=name)``, the
bench's rows ``name`` and ``name-val`` (``bench/analytic_rows.py``), the residual priors
(``learn/priors.py``), ``StreamingModel`` and :func:`batch_run.run_batch`.
"""
from __future__ import annotations

from . import qdd_methods, observer_methods, kalman_method  # noqa: F401  (each declares its methods)
from ..deprecation import warn_renamed
from ..errors import UsageError
from .method_declaration import TIP_FORCE_METHODS
from .torque_models import TORQUE_MODELS

# The method every consumer defaults to (``TipForceEstimator.analytic``, ``hybrid-dyn estimate``,
# ``examples/control_loop.py``, docs/estimator.md): the one that leads on sensors as a robot has them
# (docs/estimator.md, "Which method"). tests/system/test_default_method.py keeps them agreeing.
DEFAULT_METHOD = "momentum-observer"

__all__ = ["DEFAULT_METHOD", "TIP_FORCE_METHODS", "estimator_name", "residual_prior_names"]


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

