"""Identification: the strongest analytic baseline, a model fitted to the robot's own torques.

- :mod:`.parameters`: body inertial parameters, pseudo-inertia, log-Cholesky, validity checks;
- :mod:`.regressor`: tau = Y(q, qd, qdd) pi + F(qd) phi and its base parameters (QR);
- :mod:`.identification_methods`: the methods (``IDENTIFICATION_METHODS``); :mod:`.least_squares`: their fits;
- :mod:`.identified_model`: :func:`identify` -> :class:`IdentifiedModel` (predict, save, to_robot);
- :mod:`.excitation`: optimized finite-Fourier-series excitation trajectories (CasADi);
- :mod:`.experiment`: run an excitation trajectory on the DART plant and record it.
"""
from .least_squares import ConsistentConfig, IdentificationError
from .identification_methods import IDENTIFICATION_METHODS
from .identified_model import (IdentificationData, IdentifiedModel, LinearFriction, friction_from_file,
                    identify)
from .parameters import check_consistency
from .regressor import base_parameters, full_regressor, inertial_regressor

__all__ = ["IDENTIFICATION_METHODS", "ConsistentConfig", "IdentificationData", "IdentificationError", "IdentifiedModel",
           "LinearFriction", "base_parameters", "check_consistency", "friction_from_file", "full_regressor",
           "identify", "inertial_regressor"]
