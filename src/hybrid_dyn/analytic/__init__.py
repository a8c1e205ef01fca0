"""Analytic layer: the Pinocchio robot model and the classic tip-force baselines."""
from .robot import InputError, JointLimitWarning, Robot, SensorMount, load_robot

__all__ = ["InputError", "JointLimitWarning", "Robot", "SensorMount", "load_robot"]
