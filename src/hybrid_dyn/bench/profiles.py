"""Benchmark profiles: which scenarios, which rows, how long to train.

quick    every family on one small scenario (``make demo``), minutes on 2 cores
default  every row on paper-noext, paper-ext and mismatch-ext; the analytic rows on contact-steps (1 kHz),
         contact-steps-quiet (its base sensor at 0.05 N) and contact-steps-hardware (hardware sensors)
paper    the study's scale (1000 instances per scenario)
real     the joint-torque models that need no URDF on the three real-robot logs
         (KUKA and Baxter split by trajectory; SARCOS, one test file of 4,449
         rows, split by contiguous blocks: see src/hybrid_dyn/resources/real/sarcos.toml)

The profiles are declared in ``hybrid_dyn/resources/bench/profiles.toml`` (read into :data:`PROFILES`).
A profile is data: it names datasets (``scenarios``) and rows. A scenario is a
name (a simulated scenario of ``sim/scenarios.py``, generated and cached, or a
real set of ``data/logs/real_logs.py``, imported and cached) or the path of any dataset
in the toolkit's format, which is read as it is (:func:`profile_for_data`:
``hybrid-dyn bench --data DIR``). Each row runs where it applies; every other
row is skipped with its reason (:meth:`plan.BenchPlan.skip_reason`).
"""
from __future__ import annotations

import json
import os
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..deprecation import renamed_field, warn_renamed
from ..errors import UsageError
from ..registry import Registry
from ..resources import resource_dir
from .plan import BenchPlan, is_dataset_path, scenario_label  # noqa: F401  (served here as before)
from .rows import derived_names, study_families

# The methods BenchProfile had before the planner took them (still served, with a warning).
_PLANNED = ("preset", "train_config", "selected_rows", "applies", "skip_reason", "resolve_robot", "robot_ref",
            "dataset", "dataset_path", "generator_config", "scenario_config")



@renamed_field("generator_profile", "generator_size", why="a generator size (sim.scenarios.SIZES), not a bench profile")
@dataclass(frozen=True)
class BenchProfile:
    """A benchmark: scenarios, the rows to run on them, how to train.

    Rows are named by family (``families``, keys of ``rows.FAMILIES``) and by name
    (``rows``, rows declared in ``rows.ROWS``); they run in declaration order, each
    where it applies (:meth:`plan.BenchPlan.applies`: what a run does with a profile is its plan's).
    """

    name: str
    scenarios: tuple
    generator_size: str = "quick"
    families: tuple = field(default_factory=study_families)
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
    # Preset fields changed in every trained preset row (e.g. {"fc_units": 256}: a study's capacity control);
    # run.json records it only when set, so that reports written before it existed are of the same profile.
    preset_overrides: dict = field(default_factory=dict)

    def __post_init__(self):
        BenchPlan(self).check()  # an unknown row, family, recipe, robot or field is refused now, not after the data

    def __getattr__(self, name):
        # What a run does with a profile was its methods once; they are the planner's now (plan.BenchPlan).
        if name in _PLANNED:
            warn_renamed("BenchProfile method", name, f"hybrid_dyn.bench.plan.BenchPlan(profile).{name}", stacklevel=2)
            return getattr(BenchPlan(self), name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

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
    from .rows import FAMILIES

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


PROFILES_FILE = resource_dir("bench") / "profiles.toml"  # quick, default, real, seed-sim, paper
PROFILES = Registry("bench profile", UsageError)
for _profile in read_profiles(PROFILES_FILE):
    PROFILES.register(_profile)
# The method note of every profile under the budgeted recipe (one text, naming the recipes as learn/recipes.py does).
BUDGET_RECIPE_NOTE = tomllib.loads(PROFILES_FILE.read_text())["notes"]["budget-recipe"]


def get_profile(name: str) -> BenchProfile:
    """The profile declared as ``name``, or the error naming the known ones."""
    return PROFILES.lookup(name)


# STUDY_FAMILIES: the tuple kept by hand before the families carried their metadata.
__getattr__ = derived_names(__name__, {"STUDY_FAMILIES": ("hybrid_dyn.bench.rows.study_families()", study_families)})
