"""Analytic layer: the Pinocchio robot model and the classic tip-force baselines."""
from .base_momentum import BaseMomentumObserver
from .kalman import FusionNoise, KalmanTipForce, tare_window_noise
from .robot import InputError, JointLimitWarning, Robot, SensorMount, load_robot

__all__ = ["BaseMomentumObserver", "FusionNoise", "InputError", "JointLimitWarning", "KalmanTipForce", "Robot",
           "SensorMount", "load_robot", "tare_window_noise"]
