"""Shared helpers of the test suite (importable as ``helpers``: pyproject's ``pythonpath = ["tests"]``).

Fixtures live in ``tests/conftest.py``; the functions here build data and runs that tests in
several folders share:

- ``states``: random (q, qd, qdd) inside a robot's limits;
- ``motion``: simulated arm motions with a known tip force (RK45 on ABA, sine streams);
- ``logs``: CSV logs and their import specs, written here;
- ``bench``: a tiny bench profile for imported logs;
- ``files``: folder snapshots and the generate-in-a-child-process helper;
- ``messages``: a user-facing message read for what it names (``says``), not word for word;
- ``fault_injection``: kill a command mid-run, resume it, compare (tests/system/test_fault_injection.py);
- ``resume``: kill a training run after a checkpoint, then resume it;
- ``timelimit``: a time limit for one call (a hang fails the test).
"""
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]  # the repository root (benchmarks/, checks/, reports/, src/)
