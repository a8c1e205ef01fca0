"""How an imported log's trajectories are split into train, val and test (the import spec's ``[split]``).

Three ways, named by ``by``:

- ``"random"`` (the default, for logs of many trajectories): the reference study's split
  (:func:`~hybrid_dyn.data.dataset.split_by_instance`): ``test_frac`` of the
  trajectories to test, then ``val_frac`` of the rest to validation, at random by ``seed``.
- ``"time"`` (one long log, or several that a model must forecast): the same counts,
  but in time order: the earliest trajectories train, the next validate, the last test.
  A trajectory's time is its first sample's [s] (ties, e.g. several tables each starting
  at t = 0: by name). A model scored this way is extrapolating forward in time, as a
  user with one long log who trains on its start and tests on its end does.
- ``"list"``: the spec names each split's trajectories (``train``, ``val``, ``test``
  lists); every trajectory must be named exactly once.

A trajectory's segments (pieces between gaps) always stay in one split. The split
used is written to the manifest (``split`` beside ``splits``) and stated in the bench report.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .dataset import DatasetError, split_by_instance, split_counts

SPLIT_MODES = ("random", "time", "list")
SPLIT_NAMES = ("train", "val", "test")


class SplitSpecError(DatasetError):
    """A ``[split]`` that cannot be honoured (unknown mode, a list naming an unknown trajectory, ...)."""


@dataclass
class SplitSpec:
    """The import spec's ``[split]``: ``by`` (a mode of :data:`SPLIT_MODES`), the random split's ``seed``,
    the fractions (``test_frac`` of all trajectories, ``val_frac`` of the rest; random and time splits)
    and, for ``by = "list"``, ``lists``: split name -> trajectory names."""

    by: str = "random"
    seed: int = 0
    test_frac: float = 0.2
    val_frac: float = 0.2
    lists: dict = field(default_factory=dict)

    def problems(self) -> list[str]:
        """Why this split cannot be used, before any trajectory is known (empty: fine)."""
        out = []
        if not isinstance(self.lists, dict):
            return [f"[split] lists must map train/val/test to trajectory names, got {self.lists!r}"]
        if self.by not in SPLIT_MODES:
            out.append(f"[split] by must be one of {list(SPLIT_MODES)}, got {self.by!r}")
        unknown = sorted(set(self.lists) - set(SPLIT_NAMES))
        if unknown:
            out.append(f"[split] lists name unknown splits {unknown} (splits: {list(SPLIT_NAMES)})")
        if self.by == "list" and not self.lists:
            out.append('[split] by = "list" needs the trajectories of each split: train = [...], val = [...], '
                       'test = [...]')
        if self.by != "list" and self.lists:
            out.append(f"[split] lists of trajectories are given, but by = {self.by!r}: "
                       'drop by (the lists imply by = "list") or the lists')
        for name, names in self.lists.items():
            if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
                out.append(f"[split] {name} must be a list of trajectory names, got {names!r}")
        return out

    def describe(self, n_trajectories: int | None = None) -> str:
        """The split in words, for the manifest and the report."""
        if self.by == "list":
            return "listed in the import spec (" + ", ".join(f"{s} {len(self.lists.get(s, []))}"
                                                             for s in SPLIT_NAMES) + " trajectories)"
        how = (f"at random (seed {self.seed})" if self.by == "random"
               else "in time order (the earliest train, then val, then the latest test)")
        n = f" of {n_trajectories}" if n_trajectories is not None else ""
        return f"by trajectory{n}, {how}: test_frac {self.test_frac}, val_frac {self.val_frac} of the rest"

    def to_dict(self) -> dict:
        return {"by": self.by, "seed": self.seed, "test_frac": self.test_frac, "val_frac": self.val_frac,
                "lists": {k: list(v) for k, v in self.lists.items()}}


def split_trajectories(spec: SplitSpec, start_times: dict) -> dict:
    """``{"train": [...], "val": [...], "test": [...]}`` of trajectory names.

    start_times: trajectory name -> its first sample's time [s] (the order of a time split).
    """
    from .logs.log_readers import natural_key

    names = list(start_times)
    if spec.by == "random":
        return split_by_instance(names, spec.seed, spec.test_frac, spec.val_frac)
    if spec.by == "time":
        order = sorted(names, key=lambda n: (start_times[n], natural_key(n)))
        n_test, n_val = split_counts(len(order), spec.test_frac, spec.val_frac)
        n_train = len(order) - n_test - n_val
        return {"train": order[:n_train], "val": order[n_train:n_train + n_val], "test": order[n_train + n_val:]}
    listed = [n for s in SPLIT_NAMES for n in spec.lists.get(s, [])]
    twice = sorted({n for n in listed if listed.count(n) > 1})
    unknown = sorted(set(listed) - set(names))
    missing = sorted(set(names) - set(listed), key=natural_key)
    problems = ([f"named in more than one place: {twice}"] if twice else []) \
        + ([f"not trajectories of the log: {unknown}"] if unknown else []) \
        + ([f"in no split: {missing}"] if missing else [])
    if problems:
        raise SplitSpecError("[split] lists: " + "; ".join(problems) + f" (the log's trajectories: "
                             f"{sorted(names, key=natural_key)})")
    return {s: sorted(spec.lists.get(s, []), key=natural_key) for s in SPLIT_NAMES}


def dataset_split_text(ds) -> str:
    """How a loaded dataset is split, in words, with each split's samples: what the bench report states."""
    meta = ds.meta
    how = (meta.get("split") or {}).get("text")
    if how is None:  # a generated dataset, or one imported before the split was recorded
        how = f"by instance at random (seed {meta.get('seed')})" if meta.get("generator_version") is not None \
            else "as its manifest lists (how it was made is not recorded)"
    counts = "/".join(f"{sum(len(i) for i in ds.split(s))}" for s in SPLIT_NAMES)
    return f"{how}; train/val/test samples {counts}"


def first_instances(train: list, val: list, n_train: int, source="the dataset") -> tuple[list, list]:
    """The first ``n_train`` instances of a train split and, cut in the same proportion, of its val split.

    val keeps ``round(n_train x len(val) / len(train))`` instances, at least one: a model given less
    data has less to validate on too, as a user with that much data would (the data-scaling study,
    ``bench/studies.py``). The splits' own order is kept: a random split is already shuffled by its seed,
    and a time-ordered one then keeps its earliest instances. Asking for more than the split holds is an
    error, not a silent use of all of it.
    """
    if n_train > len(train):
        raise DatasetError(f"{source}: {n_train} training instances asked for, the train split holds {len(train)}")
    n_val = max(1, round(n_train * len(val) / len(train)))
    return list(train[:n_train]), list(val[:n_val])
