"""hybrid_dyn: physics-informed dynamics modelling of robot arms."""
from .analytic.robot import InputError, Robot, SensorMount, load_robot
from .description import Payload, RobotDescriptionError

__version__ = "0.1.0"
__all__ = ["InputError", "Payload", "Robot", "RobotDescriptionError", "SensorMount", "load_robot"]
