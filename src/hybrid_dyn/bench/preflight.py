"""The bench's checks of its datasets before the report folder is touched.

Each was a failure found only after run.json existed: an empty split (every row failed with the same
numpy message, or ``train_split_stats`` crashed), a robot of another joint count than the log (every
analytic row failed with ``q must have shape (N, 6)``), a parameter file that does not exist or is no
rigid body, and a selection of rows none of which applies ("0/0 rows ok", exit 0).
"""
from __future__ import annotations

import numpy as np

from ..data import DatasetError
from ..errors import UsageError
from ..data.data_checks import empty_split_problems


def check_dataset(profile, label: str, ds, ref) -> None:
    """Refuse ``ds`` (read from a dataset path, scenario ``label``) when the bench cannot score it with
    ``ref`` (its resolved robot): an empty split, or a robot of another joint count. Loading the robot
    here also refuses the profile's parameter set (missing, for another robot, or no rigid body)."""
    empty = empty_split_problems(ds.meta.get("splits", {}))
    if empty:
        raise DatasetError(f"dataset {ds.path} ({label}): {empty[0]}; the bench trains on train, stops on val and "
                           "scores on test (re-import it with more trajectories, e.g. [trajectories] n_blocks)")
    if not ref.described:
        return
    from ..analytic.robot import load_robot

    robot = load_robot(ref.name, params=profile.params)
    first = ds.split("train")[0]
    width = int(np.asarray(first["q"]).reshape(len(first), -1).shape[1])
    if width != robot.nv:
        raise UsageError(f"robot {ref.name!r} has {robot.nv} joints but dataset {ds.path} ({label}) logs {width}: "
                         "give the robot the log was recorded on (--robot)")


def check_rows_apply(plan, datasets: list) -> None:
    """Refuse a run in which no selected row applies to any of ``datasets`` (all read from paths):
    the bench would write an empty report and exit 0. The message lists each row's reason."""
    reasons = []
    for label, ds in datasets:
        for row in plan.selected_rows():
            reason = plan.skip_reason(row, ds)
            if reason is None:
                return
            reasons.append(f"{row.name} on {label}: {reason}")
    shown = "; ".join(reasons[:6]) + (" ..." if len(reasons) > 6 else "")
    raise UsageError(f"none of the selected rows applies to the data ({shown}); choose other rows (--rows, --families)")
