"""Identification: the strongest analytic baseline, a model fitted to the robot's own torques.

- :mod:`.parameters`: body inertial parameters, pseudo-inertia, log-Cholesky, validity checks;
- :mod:`.regressor`: tau = Y(q, qd, qdd) pi + F(qd) phi and its base parameters (QR);
- :mod:`.estimators`: ols, wls, consistent (CasADi/IPOPT), sigmoid-friction (CasADi/IPOPT);
- :mod:`.model`: :func:`identify` -> :class:`IdentifiedModel` (predict, save, to_robot);
- :mod:`.excitation`: optimized finite-Fourier-series excitation trajectories (CasADi);
- :mod:`.experiment`: run an excitation trajectory on the DART plant and record it.
"""
from .least_squares import ConsistentConfig, IdentificationError
from .identified_model import (METHODS, IdentificationData, IdentifiedModel, LinearFriction, friction_from_file,
                    identify)
from .parameters import check_consistency
from .regressor import base_parameters, full_regressor, inertial_regressor

__all__ = ["METHODS", "ConsistentConfig", "IdentificationData", "IdentificationError", "IdentifiedModel",
           "LinearFriction", "base_parameters", "check_consistency", "friction_from_file", "full_regressor",
           "identify", "inertial_regressor"]
