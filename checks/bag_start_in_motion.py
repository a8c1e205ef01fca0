"""A recorded bag whose arm moves from its first sample, replayed by ``hybrid-dyn estimate`` with the
defaults (the Panda's encoder resolution assumed, so q is filtered) and with q declared exact.

The floor: at most 0.5 N RMS on the ``ok`` samples with the defaults, every base-sensor method, so that
the tare does not take the joint filter's start-up transient for the sensor's offset. The bag is the one
``tests/estimator/test_estimate_from_bag.py`` builds (``tests/helpers/ros_bags.py``: exact q, qd of a
slow motion about home, the base wrench the rigid-body reaction with a known 4-8 N tip force, 0.1 N of
sensor noise); the figure is the one the command prints against the bag's tip sensor.

Run: .venv/bin/python checks/bag_start_in_motion.py
"""
from __future__ import annotations

import contextlib
import importlib.util
import io
import re
import sys
import tempfile
import warnings
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1] / "tests"
sys.path.insert(0, str(TESTS))
from helpers.ros_bags import panda_signals, ros_spec, write_bag  # noqa: E402

import hybrid_dyn as hd  # noqa: E402
from hybrid_dyn.cli import main  # noqa: E402

FLOOR_N = 0.5
METHODS = ("base-wrench", "base-momentum", "kalman-fusion")


def _known_force():
    spec = importlib.util.spec_from_file_location("bag_test", TESTS / "estimator" / "test_estimate_from_bag.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main_check() -> int:
    warnings.simplefilter("ignore")
    test = _known_force()
    robot = hd.load_robot("panda")
    tmp = Path(tempfile.mkdtemp(prefix="bag-start-in-motion-"))
    sig = panda_signals(robot, n=test.N, hz=test.HZ, force=test.known_force(), base_noise=0.1, seed=3)
    spec = ros_spec(tmp / "spec", write_bag(tmp / "run", sig, kind="mcap"))
    failed = False
    print(f"{'method':15s} {'encoders':16s} {'RMS [N]':>8s} {'ok samples':>10s}")
    for method in METHODS:
        for label, extra in (("defaults", []), ("declared exact", ["--encoder-resolution", "0"])):
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                main(["estimate", str(spec), "--method", method, *extra, "--out", str(tmp / f"{method}-{len(extra)}.csv")])
            rms, n_ok = re.search(r"([0-9.]+) N RMS over the (\d+) samples", printed.getvalue()).groups()
            verdict = ""
            if label == "defaults":
                met = float(rms) <= FLOOR_N
                failed |= not met
                verdict = "met" if met else "NOT met"
            print(f"{method:15s} {label:16s} {float(rms):8.4f} {int(n_ok):10d}  {verdict}")
    print(f"floor: <= {FLOOR_N} N RMS with the defaults: {'NOT met' if failed else 'met'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main_check())
