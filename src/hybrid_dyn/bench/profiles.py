"""Benchmark profiles: which scenarios, which rows, how long to train (``hybrid-dyn bench --profile NAME``).

The profiles are data, declared in ``hybrid_dyn/resources/bench/profiles.toml`` and read into
:data:`PROFILES` (this module is their catalogue; ``hybrid-dyn bench --help`` lists them with their
scenarios). A profile names its datasets (``scenarios``: simulated scenarios, real sets or dataset paths)
and its rows, by family and by name, explicitly: a family or row declared later changes no shipped profile.
Each row runs where it applies; every other row is skipped with its reason (:class:`plan.BenchPlan`).
"""
from __future__ import annotations

import json
import os
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..errors import UsageError
from ..registry import Registry
from ..resources import resource_dir
from .plan import BenchPlan
from .families import FAMILIES


@dataclass(frozen=True)
class BenchProfile:
    """A benchmark: scenarios, the rows to run on them, how to train.

    Rows are named by family (``families``, names in ``FAMILIES``: none unless named) and by name
    (``rows``, rows declared in ``rows.ROWS``); they run in declaration order, each
    where it applies (:meth:`plan.BenchPlan.applies`: what a run does with a profile is its plan's).
    """

    name: str
    scenarios: tuple
    generator_size: str = "quick"
    families: tuple = ()
    rows: tuple = ()
    recipe: str = "budget"  # learn.recipes.RECIPES: the budgeted recipe unless a profile says otherwise
    train: dict = field(default_factory=dict)  # TrainConfig fields on top of the recipe
    generator_overrides: dict = field(default_factory=dict)  # GeneratorConfig fields, every scenario
    # scenario -> GeneratorConfig fields, that one only (a real set: fields of its import spec, data.logs.real_logs.real_dataset)
    scenario_overrides: dict = field(default_factory=dict)
    workers: int = 2
    torch_threads: int = 1  # see runner.run_bench: one thread is fastest for these nets
    notes: tuple = ()  # method notes printed in the report (fixed before any result)
    # Scenarios that run only some families (scenario -> families); the rest run every row.
    scenario_families: dict = field(default_factory=dict)
    seed: int = 0
    # The analytic model (None: each dataset's own robot, the robot's default parameters, its own tool).
    robot: str | None = None  # a robot name for every dataset (description.ROBOT_NAME_HELP)
    params: str | None = None  # nominal parameter set (a name or a JSON path): analytic rows and residual priors
    tool: str | None = None  # the tool of every dataset's robot ("none": the bare flange)
    # Preset fields changed in every trained preset row (e.g. {"fc_units": 256}: a study's capacity arm);
    # run.json records it only when set, so that reports written before it existed are of the same profile.
    preset_overrides: dict = field(default_factory=dict)

    def __post_init__(self):
        BenchPlan(self).check()  # an unknown row, family, recipe, robot or field is refused now, not after the data

    def to_dict(self) -> dict:
        """The profile as run.json records it (JSON types: lists for tuples), so that a profile and a
        report's ``run.json["profile"]`` compare equal exactly when they are the same profile. The generator
        size keeps the key run.json has always recorded it under, ``generator_profile`` (the report reads it);
        fields added after reports were committed (``preset_overrides``) are recorded only when set."""
        d = json.loads(json.dumps({("generator_profile" if k == "generator_size" else k): v
                                   for k, v in asdict(self).items()}))
        if not d["preset_overrides"]:
            del d["preset_overrides"]
        return d


def profile_for_data(paths, robot: str | None = None, params: str | None = None, tool: str | None = None,
                     recipe: str = "budget", name: str = "data", **fields) -> BenchProfile:
    """The profile of ``hybrid-dyn bench --data DIR ...``: every declared row on the datasets at ``paths``,
    each where it applies. ``robot``, ``params``, ``tool``, ``recipe``: see :class:`BenchProfile`;
    ``fields``: any other of its fields (``train``, ``workers``, ``families``, ...)."""
    paths = tuple(str(p) for p in ([paths] if isinstance(paths, (str, os.PathLike)) else paths))
    if not paths:
        raise UsageError("give at least one dataset (--data DIR)")
    fields.setdefault("families", tuple(FAMILIES))
    return BenchProfile(name=name, scenarios=paths, robot=robot, params=params, tool=tool, recipe=recipe, **fields)


def as_tuples(value):
    """A declaration read from TOML with its arrays as tuples (as the dataclasses hold them), dicts kept."""
    if isinstance(value, list):
        return tuple(as_tuples(v) for v in value)
    if isinstance(value, dict):
        return {k: as_tuples(v) for k, v in value.items()}
    return value


def read_profiles(path: Path) -> list[BenchProfile]:
    """The profiles a TOML file declares (``[profiles.NAME]`` tables of :class:`BenchProfile` fields; a note
    ``{shared = "KEY"}`` stands for ``[notes].KEY``), each checked as it is made."""
    doc = tomllib.loads(Path(path).read_text())
    shared = doc.get("notes", {})
    profiles = []
    for name, declared in doc.get("profiles", {}).items():
        declared = as_tuples(declared)
        notes = tuple(shared[n["shared"]] if isinstance(n, dict) else n for n in declared.pop("notes", ()))
        try:
            profiles.append(BenchProfile(name=name, notes=notes, **declared))
        except TypeError as err:  # a field BenchProfile does not have
            raise UsageError(f"{path}: profile {name!r}: {err}") from None
    return profiles


PROFILES_FILE = resource_dir("bench") / "profiles.toml"
PROFILES = Registry("bench profile", UsageError).register_all(read_profiles(PROFILES_FILE))
# The method note of every profile under the budgeted recipe (one text, naming the recipes as learn/recipes.py does).
BUDGET_RECIPE_NOTE = tomllib.loads(PROFILES_FILE.read_text())["notes"]["budget-recipe"]

