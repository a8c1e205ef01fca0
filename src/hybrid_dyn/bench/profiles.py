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
row is skipped with its reason (:meth:`BenchProfile.skip_reason`).
"""
from __future__ import annotations

import json
import os
import tomllib
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

from ..data import DatasetError, load_dataset
from ..deprecation import renamed_field
from ..errors import UsageError
from ..registry import Registry
from ..resources import resource_dir
from .catalog import select_rows
from .rows import Row, derived_names, study_families



@renamed_field("generator_profile", "generator_size", why="a generator size (sim.scenarios.SIZES), not a bench profile")
@dataclass(frozen=True)
class BenchProfile:
    """A benchmark: scenarios, the rows to run on them, how to train.

    Rows are named by family (``families``, keys of ``rows.FAMILIES``) and by name
    (``rows``, rows declared in ``rows.ROWS``); they run in declaration order, each
    where it applies (:meth:`applies`).
    """

    name: str
    scenarios: tuple
    generator_size: str = "quick"
    families: tuple = field(default_factory=study_families)
    rows: tuple = ()
    recipe: str = "budget"  # learn.recipes.RECIPES: the budgeted recipe unless a profile says otherwise
    train: dict = field(default_factory=dict)  # TrainConfig fields on top of the recipe
    generator_overrides: dict = field(default_factory=dict)  # GeneratorConfig fields, every scenario
    # scenario -> GeneratorConfig fields, that one only (a real set: fields of its import spec, data.real.real_dataset)
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
        self.selected_rows()  # an unknown row or family is refused now, not after the data are made
        self.train_config()  # so is an unknown recipe or a bad training field
        if self.robot is not None:
            self.resolve_robot(self.robot)  # a name the toolkit cannot serve is refused now, with the accepted ones
        if self.preset_overrides:  # an unknown Preset field is refused now
            from ..learn.presets import Preset

            known = {f.name for f in fields(Preset)} - {"name"}
            bad = sorted(set(self.preset_overrides) - known)
            if bad:
                raise UsageError(f"profile {self.name!r}: preset_overrides {bad} are not Preset fields")
        if self.params is not None and str(self.params).endswith(".json"):
            from ..description import read_param_file

            read_param_file(self.params)  # missing, malformed or no rigid body: refused before any work

    def preset(self, name: str):
        """The preset a preset row ``name`` trains: its own, or with :attr:`preset_overrides` (a new
        :class:`~hybrid_dyn.learn.presets.Preset`; the name stays, the fields and so the fingerprint change)."""
        if not self.preset_overrides:
            return name
        from ..learn.presets import get_preset

        return get_preset(name).replace(**self.preset_overrides)

    def train_config(self):
        from ..learn import TrainConfig

        # --params is the nominal model: the residual rows' priors sit on it too (identified rows replace it).
        nominal = {"analytic_params": self.params} if self.params is not None else {}
        return TrainConfig.recipe(self.recipe, **{"seed": self.seed, **nominal, **self.train})

    def selected_rows(self) -> list[Row]:
        """The rows this profile runs (where they apply), in declaration order."""
        return select_rows(names=self.rows, families=self.families)

    def applies(self, row: Row, ds) -> bool:
        """Whether a row can run on a dataset (:meth:`skip_reason` is None)."""
        return self.skip_reason(row, ds) is None

    def skip_reason(self, row: Row, ds) -> str | None:
        """Why ``row`` does not run on ``ds`` (e.g. "needs base_wrench", "needs a URDF for robot 'x'"),
        or None when it runs: the fields it declares exist, and a URDF where it needs one."""
        only = self.scenario_families.get(ds.meta.get("scenario"))
        if only is not None and row.family not in only:
            return f"this profile runs only the {', '.join(only)} rows on {ds.meta.get('scenario')}"
        config = ds.meta.get("config", {})
        if row.task == "tip_force" and "pulses" in config and config["pulses"] is None \
                and config.get("contact_steps") is None:
            return "no external force in this scenario: nothing to estimate at the tip"
        needs = tuple(row.needs) + tuple(row.more_needs(ds) if row.more_needs else ())
        missing = [f for f in dict.fromkeys(needs) if f not in ds.fields]
        if missing:
            return f"needs {', '.join(missing)}"
        if row.needs_urdf and not self.robot_ref(ds).described:
            return f"needs a URDF for robot {self.robot_ref(ds).name!r} (known for data only)"
        return None

    def resolve_robot(self, name: str):
        """``description.resolve_robot`` of ``name`` with this profile's tool (replacing the name's own tool)."""
        from ..description import parse_robot_name, resolve_robot

        if self.tool is None:
            return resolve_robot(name)
        base, _, payload = parse_robot_name(name)
        return resolve_robot(base, tool=self.tool, payload=payload)

    def robot_ref(self, ds):
        """What the analytic model of ``ds`` is: this profile's ``robot``, else the dataset's own, with ``tool``."""
        name = self.robot or ds.meta.get("robot")
        if not name:
            raise DatasetError(f"dataset {ds.path} does not name its robot (manifest key 'robot'); give one (--robot)")
        return self.resolve_robot(name)

    def dataset(self, scenario: str, data_root: Path, log=print, executor=None):
        """The scenario's dataset: a dataset path is read as it is; a simulated scenario is generated once
        and cached by its config hash (real-robot logs: imported once, cached by spec and file checksums)."""
        if is_dataset_path(scenario):
            return load_dataset(scenario)
        if scenario.startswith("real-"):
            from ..data.logs.real_logs import real_dataset

            spec = self.scenario_overrides.get(scenario, {})  # e.g. another split of the same log
            return load_dataset(real_dataset(scenario, Path(data_root), log=log, **spec))
        from ..sim.generator import generate_dataset

        cfg = self.scenario_config(scenario)
        path = self.dataset_path(scenario, data_root)
        try:
            return load_dataset(path)
        except DatasetError:
            log(f"[bench] generating {scenario} ({self.generator_size}) into {path}")
            generate_dataset(cfg, path, workers=self.workers, executor=executor)
            return load_dataset(path)

    def dataset_path(self, scenario: str, data_root: Path) -> Path:
        """Where a simulated scenario's dataset is cached: one folder per generator size and config hash."""
        return Path(data_root) / f"{scenario}-{self.generator_size}-{self.scenario_config(scenario).config_hash()}"

    def generator_config(self, scenario: str, ds):
        """The generator config that simulated ``ds``: a named scenario's (:meth:`scenario_config`), or for a
        dataset path the config its manifest records (the plant an identification run is recorded on)."""
        if is_dataset_path(scenario):
            from ..sim.scenarios import GeneratorConfig

            return GeneratorConfig.from_dict(ds.meta["config"])
        return self.scenario_config(scenario)

    def scenario_config(self, scenario: str):
        """The generator config of one of this profile's simulated scenarios."""
        from ..sim.scenarios import scenario_config

        return scenario_config(scenario, self.generator_size, seed=self.seed,
                               **{**self.generator_overrides, **self.scenario_overrides.get(scenario, {})})

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


def is_dataset_path(scenario: str) -> bool:
    """Whether a profile's scenario entry is a dataset path (anything but a simulated scenario's or a
    real set's name)."""
    from ..data.logs.real_logs import REAL_SETS
    from ..sim.scenarios import SCENARIOS

    return str(scenario) not in SCENARIOS and str(scenario) not in REAL_SETS


def scenario_label(scenario: str, ds) -> str:
    """The scenario's name in results.csv and the tables: a named scenario's name; for a dataset path,
    its manifest's ``scenario``, or the folder's name."""
    if not is_dataset_path(scenario):
        return scenario
    return str(ds.meta.get("scenario") or Path(os.path.abspath(scenario)).name)


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
