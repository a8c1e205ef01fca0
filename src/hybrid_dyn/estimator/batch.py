"""``estimate_tip_force()``: the stateless batch form of the estimator, for offline use."""
from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

from ..analytic.robot import InputError, Robot, load_robot
from ..analytic.tare import tared_base_wrench
from ..analytic.tip_force import tip_force_from_base_wrench

_thread_local = threading.local()


def _robot_for_thread(name: str) -> Robot:
    robots = getattr(_thread_local, "robots", None)
    if robots is None:
        robots = _thread_local.robots = {}
    if name not in robots:
        robots[name] = load_robot(name, num_threads=1)
    return robots[name]


def estimate_tip_force(q, qd, qdd, base_wrench=None, tau_J=None, model=None, robot: str = "panda",
                       tare_samples: int = 0) -> np.ndarray:
    """Stateless batch tip-force estimate (N, 3) [N] for offline use.

    model=None: the analytic base-wrench method (needs base_wrench (N, 6));
    tare_samples > 0 tares the base sensor on that many contact-free first
    samples (``analytic/tare.py``), as the streaming estimator does.
    model: a trained model directory (or a loaded model); its inputs decide
    which of base_wrench / tau_J are needed. Thread-safe.
    """
    if model is None:
        if base_wrench is None:
            raise InputError("the analytic base-wrench method needs base_wrench (N, 6)")
        r = _robot_for_thread(robot)
        if tare_samples > 0:
            base_wrench = tared_base_wrench(r, np.atleast_2d(q), np.atleast_2d(qd), np.atleast_2d(qdd),
                                            np.atleast_2d(base_wrench), tare_samples)
        return tip_force_from_base_wrench(r, q, qd, qdd, base_wrench)
    from ..learn.stream_predictor import StreamingModel

    m = model if isinstance(model, StreamingModel) else StreamingModel.load(Path(model))
    return m.predict_arrays(q, qd, qdd, base_wrench, tau_J)
