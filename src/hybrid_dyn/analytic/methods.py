"""The catalogue of the analytic tip-force methods: importing it declares the built-in ones in
:data:`TIP_FORCE_METHODS` (``method_declaration.py``), each by its own module, in this order (the
bench's row order). A consumer imports the registry from here; a new method's module adds one line here
(or is imported by its own package), and imports from ``method_declaration`` itself.

Everything else is built from the registry: ``TipForceEstimator.analytic(robot, method=name)``, the
bench's rows ``name`` and ``name-val`` (``bench/analytic_rows.py``), the residual priors
(``learn/priors.py``), ``StreamingModel`` and :func:`batch_run.run_batch`.
"""
from . import qdd_methods, observer_methods, kalman_method  # noqa: F401  (each declares its methods)
from .method_declaration import TIP_FORCE_METHODS

# The method every consumer defaults to (``TipForceEstimator.analytic``, ``hybrid-dyn estimate``,
# ``examples/control_loop.py``, docs/estimator.md): the one that leads on sensors as a robot has them
# (docs/estimator.md, "Which method"). tests/system/test_default_method.py keeps them agreeing.
DEFAULT_METHOD = "momentum-observer"

__all__ = ["DEFAULT_METHOD", "TIP_FORCE_METHODS"]
