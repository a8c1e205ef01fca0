"""What a row's numbers cannot show, written beside the row.

A bench on a log that cannot identify or test what its rows claim still prints numbers: a dead torque
channel made ``identified-consistent`` the headline (its nMSE averaged over the joints that had variance)
on parameters no Panda has; a test split at a standstill headlined ``rnea`` at the noise floor, friction
and inertia never tested. :func:`review_row` gives each scored row its status and its notes:

- status ``implausible`` (``results.SCORED_STATUSES``): an identified row whose parameters (or those of its
  prior) lie outside the robot's bounds (``identify.plausibility``): scored, in the tables with the bodies
  named, never a family's best;
- notes (results.csv ``notes``, joined by :data:`NOTE_SEPARATOR`, drawn beside the row in the tables and
  under the headline): an nMSE or a loss undefined over a component of zero variance (``metrics``), a
  joint under ``MOTION_THRESHOLDS.min_range_rad`` of motion in the data the row was fitted on, a
  condition number that leaves the fit undetermined, a joint-torque test split at a standstill.

The notes are results.csv cells, so ``hybrid-dyn report`` draws them from the file the digest covers.
"""
from __future__ import annotations

import numpy as np

from ..data.data_checks import MOTION_THRESHOLDS, range_of_motion_problems, standstill_problems
from .metrics import zero_variance_components

IMPLAUSIBLE = "implausible"
NOTE_SEPARATOR = " | "
AXES = "xyz"


def row_notes(row: dict) -> list[str]:
    """A results.csv row's notes as a list (none for a report written before the column)."""
    text = row.get("notes") or ""
    return [n for n in text.split(NOTE_SEPARATOR) if n]


def _components(task: str, idx, robot) -> str:
    if task == "tip_force":
        return ", ".join(f"axis {AXES[j]}" for j in idx)
    names = getattr(robot, "joint_names", None)
    return ", ".join(f"joint {j + 1}" + (f" ({names[j]})" if names and j < len(names) else "") for j in idx)


def scenario_motion(ctx) -> dict:
    """The motion checks of a scenario's dataset, once per scenario: ``train`` (joints under the range of
    motion to identify, in the train split) and ``test`` (a test split at a standstill)."""
    if "motion-checks" not in ctx.cache:
        ds = ctx.dataset
        names = getattr(ctx.robot, "joint_names", None)
        train, test = ds.split("train"), ds.split("test")
        cat = lambda insts, k: np.concatenate([np.asarray(i[k]) for i in insts])  # noqa: E731
        checks = {"train": [], "test": []}
        if "q" in ds.fields and train:
            checks["train"] = range_of_motion_problems(cat(train, "q"), names, "the train split", MOTION_THRESHOLDS)
        if "qd" in ds.fields and "qdd" in ds.fields and test:
            checks["test"] = standstill_problems(cat(test, "qd"), cat(test, "qdd"), "the test split", MOTION_THRESHOLDS)
        ctx.cache["motion-checks"] = checks
    return ctx.cache["motion-checks"]


def review_row(spec, ctx, pred_obj, target: str, train_std, test_target) -> tuple[str, list[str]]:
    """(status, notes) of a scored row: ``implausible`` when its review finds parameters outside the robot's
    bounds, else ``ok``; the notes as the module says. ``train_std`` (C,): the train split's std of the
    target; ``test_target`` (N, C): the test split's."""
    notes = []
    flat = zero_variance_components(test_target)
    if flat:
        notes.append(f"nMSE undefined: the test split's {target} of {_components(spec.task, flat, ctx.robot)} has "
                     "zero variance (a dead channel?)")
    flat_train = [int(j) for j in np.flatnonzero(~(np.asarray(train_std, float) > 0))]
    if flat_train:
        notes.append(f"losses undefined: the train split's {target} of {_components(spec.task, flat_train, ctx.robot)}"
                     " has zero variance (the losses are standardised by it)")
    problems, fit_notes = pred_obj.review() if pred_obj.review is not None else ([], [])
    notes += fit_notes
    motion = scenario_motion(ctx)
    # A row fitted on the train split (trained or with fitted weights) cannot know a joint it never saw move;
    # the identified rows say the same of their own identification data (their review).
    if spec.trains or pred_obj.training is not None or pred_obj.n_params:
        notes += motion["train"]
    if spec.task == "joint_torque":  # a torque model claims dynamics: a standstill tests only gravity
        notes += motion["test"]
    return (IMPLAUSIBLE if problems else "ok"), problems + notes
