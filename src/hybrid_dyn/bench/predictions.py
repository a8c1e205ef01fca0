"""predictions.h5 beside results.csv: every row's test predictions and the targets they are scored on,
so that the report's figures are redrawn from files (``hybrid-dyn report DIR``), with no dataset.

Layout (HDF5, float64 arrays, one per test instance, in physical units)::

    /<scenario>/test/<instance>/t               (T,)    s, the instance's time
    /<scenario>/test/<instance>/<target>        (T, C)  the logged target (tip_force [N], tau_m [Nm])
    /<scenario>/test/<instance>/tip_force_truth (T, 3)  N, the noise-free tip force (simulated sets)
    /<scenario>/<task>/<model>/<instance>       (T, C)  the row's prediction

Each group's ``order`` attribute (JSON) lists its members in the order the bench scored them (HDF5
lists names alphabetically); a reader reads only what ``order`` lists. A run's first write starts the
file anew (a new file renamed into place); every later row is written in place (copying the
whole file per row cost a copy of up to 1.6 GB per row), atomically per row: its arrays go into a group
under a temporary name, the file is flushed, then the group is renamed to the row's name and listed in
``order``, and the file flushed again. A kill before the rename leaves the temporary group unlisted (a
reader never sees half a row; the next writer of the file deletes it) and the rows before it intact.
HDF5 keeps no journal: a kill in the middle of a flush can still leave the file unreadable, which a
resumed bench starts anew, and ``hybrid-dyn report`` then names the rows whose predictions it lacks.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..errors import HybridDynError
from ..outputs import unique_temp

PREDICTIONS_FILE = "predictions.h5"
TEST_GROUP = "test"  # beside the task groups: a task is tip_force or joint_torque, never "test"


class PredictionsError(HybridDynError, ValueError):
    """predictions.h5 is missing, unreadable, or lacks what a figure needs."""


def _key(name: str, what: str) -> str:
    name = str(name)
    if not name or "/" in name or name in (".", ".."):
        raise PredictionsError(f"{what} {name!r} cannot name an HDF5 group in {PREDICTIONS_FILE} (empty, '/', '.')")
    return name


def _ordered(group, name: str) -> None:
    order = json.loads(group.attrs.get("order", "[]"))
    if name not in order:
        group.attrs["order"] = json.dumps(order + [name])


def _readable(path: Path) -> bool:
    import h5py

    try:
        with h5py.File(path, "r"):
            return True
    except (OSError, ValueError):
        return False


PARTIAL = ".partial-"  # a group being written: "<name>.partial-<pid>", renamed to <name> once complete


class PredictionWriter:
    """Writes one bench run's predictions.h5; the first write of a run starts the file anew, unless
    ``resume``: then it adds to the file an earlier invocation of the same profile left (each row's
    predictions are replaced as it is scored again), so that an invocation interrupted before its first
    row leaves the earlier rows' predictions beside the results.csv that still lists them. An
    unreadable file is started anew (its rows are then refused by ``hybrid-dyn report``, named)."""

    def __init__(self, path, resume: bool = False):
        self.path = Path(path)
        self.started = bool(resume) and _readable(self.path)

    def _update(self, fill) -> None:
        """``fill(f)`` on the file: a new file renamed into place on the run's first write, else in place."""
        import h5py

        if not self.started:
            tmp = unique_temp(self.path)
            try:
                with h5py.File(tmp, "w") as f:
                    fill(f)
                os.replace(tmp, self.path)
            finally:
                if tmp.exists():
                    tmp.unlink()
            self.started = True
            return
        with h5py.File(self.path, "a") as f:
            fill(f)

    def test_data(self, scenario: str, instances: list, targets: list) -> None:
        """The scenario's test instances: their time, the ``targets`` fields they hold and the noise-free tip force."""
        def fill(f):
            root = f.require_group(_key(scenario, "scenario"))
            _ordered(f, scenario)
            grp = root.require_group(TEST_GROUP)
            for inst in instances:
                def arrays(g, inst=inst):
                    g["t"] = np.asarray(inst.t, dtype=np.float64)
                    for field in targets:
                        g[field] = np.asarray(inst[field], dtype=np.float64)
                    if "tip_force" in targets and "tip_force" in inst.truth:
                        g["tip_force_truth"] = np.asarray(inst.truth["tip_force"], dtype=np.float64)

                # a resumed run's file: this run's test data replace it
                _write_group(f, grp, _key(inst.name, "instance"), arrays)

        self._update(fill)

    def row(self, scenario: str, task: str, model: str, names: list, preds: list) -> None:
        """One row's test predictions, one array per instance (``names`` in the test split's order)."""
        def fill(f):
            grp = f.require_group(_key(scenario, "scenario")).require_group(_key(task, "task"))
            _ordered(f[scenario], task)

            def arrays(g):
                g.attrs["order"] = json.dumps([str(n) for n in names])
                for name, p in zip(names, preds):
                    g[_key(name, "instance")] = np.asarray(p, dtype=np.float64)

            _write_group(f, grp, _key(model, "model"), arrays)

        self._update(fill)


def _write_group(f, parent, name: str, arrays) -> None:
    """``arrays(group)`` into ``parent[name]``, atomically as far as HDF5 allows: written under a temporary
    name and flushed, then renamed over any old group of that name and listed in ``order``, and flushed."""
    for stale in [k for k in parent if PARTIAL in k]:  # a killed write's leftovers: never listed, never read
        del parent[stale]
    tmp = f"{name}{PARTIAL}{os.getpid()}"
    arrays(parent.create_group(tmp))
    f.flush()
    if name in parent:
        del parent[name]
    parent.move(tmp, name)
    _ordered(parent, name)
    f.flush()


class Predictions:
    """predictions.h5 read back (every array loaded on first use of its scenario)."""

    def __init__(self, path):
        import h5py

        self.path = Path(path)
        if not self.path.is_file():
            raise PredictionsError(f"no {self.path}: this report predates {PREDICTIONS_FILE} (rerun the bench)")
        try:
            with h5py.File(self.path, "r") as f:
                self._data = {s: self._read_scenario(f[s]) for s in json.loads(f.attrs.get("order", "[]"))}
        except (OSError, KeyError, ValueError) as err:
            raise PredictionsError(f"{self.path} is not a readable {PREDICTIONS_FILE}: {err}") from err

    @staticmethod
    def _read_scenario(g) -> dict:
        out = {"test": [], "rows": {}}
        test = g[TEST_GROUP]
        for name in json.loads(test.attrs["order"]):
            out["test"].append({"name": name, **{k: test[name][k][()] for k in test[name]}})
        for task in json.loads(g.attrs.get("order", "[]")):
            if task == TEST_GROUP:
                continue
            for model in json.loads(g[task].attrs.get("order", "[]")):
                m = g[task][model]
                out["rows"][(task, model)] = [m[n][()] for n in json.loads(m.attrs["order"])]
        return out

    def scenarios(self) -> list[str]:
        return list(self._data)

    def test(self, scenario: str) -> list[dict]:
        """The scenario's test instances: dicts of name, t and the stored targets."""
        return self._data.get(scenario, {"test": []})["test"]

    def get(self, scenario: str, task: str, model: str) -> list | None:
        """The row's predictions, one (T, C) array per test instance; None when it has none."""
        return self._data.get(scenario, {"rows": {}})["rows"].get((task, model))
