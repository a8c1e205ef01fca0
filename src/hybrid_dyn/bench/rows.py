"""The bench's rows, each declared once with ``ROWS.register(Row(...))``: what it is, what it needs, how it is built.

A :class:`Row` is everything the harness, the report and the tests know about one model row. The
rows that ship are declared by ``analytic_rows.py``, ``learned_rows.py`` (one per preset) and
``identified_rows.py``, in the order results.csv lists them; ``catalog.py`` imports the three, so
that :data:`ROWS` is complete. A row declared without the fields it reads is refused here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..data.dataset import FIELD_UNITS
from ..errors import UsageError
from ..registry import Registry
from .families import FAMILIES

# task -> the logged field its rows are scored against (PROTOCOL 4: the commanded motor torque).
TASK_TARGET = {"tip_force": "tip_force", "joint_torque": "tau_m"}

@dataclass
class Predictor:
    """What the harness needs from any model: batch predictions per instance and one timed single call."""

    predict: Callable[[list], list]  # instances -> list of (T, C) arrays in physical units
    # The call a user makes per sample: single_call(instance, k) -> (C,). The harness feeds one run's
    # samples in order from its start (k = 0, 1, 2, ...: an observer or a streaming model must see the
    # run as a control loop does) and times the calls after the first ``warmup_calls``.
    single_call: Callable[[object, int], np.ndarray] | None = None
    train_seconds: float = 0.0
    # CPU time [s] of training as the model's file recorded it (NaN: not recorded, a model trained before
    # CPU time was recorded); None: the row was fitted in the bench's process by ``build``, whose CPU time is the figure.
    train_cpu_seconds: float | None = None
    n_params: int = 0
    inputs: str = ""
    training: dict | None = None  # trained rows: ``training_summary`` of the model's config
    # A hybrid row (a correction on a physics prior): whether validation kept the prior, from
    # prior_kept_text ("all", "none", "joints 2, 5"); None for a row with no prior.
    prior_kept: str | None = None
    warmup_calls: int = 1  # untimed calls first (lazy allocations, a stream's window and tare)
    # Called after the row's predictions: (problems, notes) of what it was fitted to. Problems (identified
    # parameters outside the robot's bounds) mark the row implausible; notes go beside it (row_checks.py).
    review: Callable[[], tuple] | None = None
    # An estimator row's error-bar coverage: called once the row is scored, -> the share of the
    # test samples with an error bar (after the window) whose error is within 2 sigma on every axis.
    sigma_coverage: Callable[[], float] | None = None


@dataclass(frozen=True)
class Row:
    """One bench row, declared once.

    name: the row's name in results.csv and the tables. task: a key of :data:`TASK_TARGET`.
    family: a key of :data:`FAMILIES`. needs: the dataset fields the row reads, its target
    included (no default: a row must say). needs_urdf: whether it needs a description of the
    dataset's robot. build(ds, ctx) -> :class:`Predictor`. trains: a trained row (with
    a loss curve). reference: the label of a reference row (in the tables, never a family's
    best), None for a contender. more_needs(ds) -> fields: what it needs beyond ``needs`` on that
    dataset (identified rows fit on an imported log's own torques). prior_row: the row that is this
    hybrid row's physics prior exactly (residual-rnea: rnea), so that the report can set one
    against the other; None for a row with no such row.
    """

    name: str
    task: str
    family: str
    needs: tuple
    needs_urdf: bool
    build: Callable
    trains: bool = False
    reference: str | None = None
    more_needs: Callable | None = None
    prior_row: str | None = None

    def __post_init__(self):
        where = f"bench row {self.name!r}"
        if self.task not in TASK_TARGET:
            raise UsageError(f"{where}: task must be one of {', '.join(TASK_TARGET)}, got {self.task!r}")
        if FAMILIES.missing([self.family]):
            raise UsageError(f"{where}: family must be one of {', '.join(FAMILIES)}, got {self.family!r}")
        if not isinstance(self.needs, (tuple, list)) or not self.needs:
            raise UsageError(f"{where}: declare the dataset fields it reads (needs), got {self.needs!r}")
        unknown = [f for f in self.needs if f not in FIELD_UNITS]
        if unknown:
            raise UsageError(f"{where}: needs unknown fields {unknown}; known: {', '.join(FIELD_UNITS)}")
        if TASK_TARGET[self.task] not in self.needs:
            raise UsageError(f"{where}: needs must hold its target {TASK_TARGET[self.task]!r}, got {tuple(self.needs)}")
        if not isinstance(self.needs_urdf, bool):
            raise UsageError(f"{where}: needs_urdf must be True or False, got {self.needs_urdf!r}")
        if not callable(self.build):
            raise UsageError(f"{where}: build must be a callable (ds, ctx) -> Predictor")
        object.__setattr__(self, "needs", tuple(self.needs))


ROWS = Registry("bench row", UsageError)  # results list rows in declaration order


def is_physics_result(result: dict) -> bool:
    """Whether a results.csv row is physics alone: an analytic or identified row with no trained part and no
    fitted weights (``n_params`` 0; the residual GP on the identified model has them), never a reference."""
    row = ROWS.get(result["model"])
    if row is None:
        return False
    family = FAMILIES[row.family]  # physics: nothing fitted, or parameters identified from data
    return (not family.fitted or family.identifies_parameters) and not row.trains \
        and row.reference is None and not float(result.get("n_params") or 0)


def is_physics_family(family: str) -> bool:
    """Whether a study's line label is a physics comparator ("physics", "physics on q, qd, qdd";
    ``studies.choose_rows``) rather than a learned family."""
    return family == "physics" or family.startswith("physics on ")


def prior_kept_text(kept) -> str:
    """Per-output flags "validation kept the prior" in words: "all", "none" or "joints 2, 5" (1-based)."""
    kept = [bool(k) for k in kept]
    if all(kept):
        return "all"
    if not any(kept):
        return "none"
    return "joints " + ", ".join(str(j + 1) for j, k in enumerate(kept) if k)

