"""hybrid_dyn: physics-informed dynamics modelling of robot arms."""
from .analytic.robot import InputError, Robot, SensorMount, load_robot
from .description import Payload, RobotDescriptionError
from .estimator import EstimatorStatus, TipForceEstimator, estimate_tip_force

__version__ = "0.1.0"
__all__ = ["EstimatorStatus", "InputError", "Payload", "Robot", "RobotDescriptionError", "SensorMount",
           "TipForceEstimator", "estimate_tip_force", "load_robot"]
