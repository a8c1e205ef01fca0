"""The bench's planner: what a run does with a profile (:class:`~hybrid_dyn.bench.profiles.BenchProfile`,
plain data declared in ``resources/bench/profiles.toml``).

Following a profile through ``runner.run_bench``, a :class:`BenchPlan`

1. checks the profile before any work (:meth:`BenchPlan.check`),
2. makes or reads each scenario's dataset (:meth:`~BenchPlan.dataset`: a dataset path as it is, a real set
   imported once, a simulated scenario generated once and cached by its config hash),
3. resolves the analytic model's robot of each dataset (:meth:`~BenchPlan.robot_ref`),
4. selects the rows (:meth:`~BenchPlan.selected_rows`) and says why each that does not apply is skipped
   (:meth:`~BenchPlan.skip_reason`),
5. builds the training config of the learned rows (:meth:`~BenchPlan.train_config`, :meth:`~BenchPlan.preset`).

The profile records itself (``BenchProfile.to_dict``, run.json); the plan holds no state of its own.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Callable

from ..data import DatasetError, load_dataset
from ..errors import UsageError
from .catalog import select_rows
from .rows import Row


@dataclass(frozen=True)
class BenchPlan:
    """What a run does with ``profile`` (a ``BenchProfile``): its checks, datasets, robots, rows and training."""

    profile: object

    def check(self) -> None:
        """Refuse a profile the run could not follow, before any data are made: an unknown row or family,
        recipe, training field, robot (naming the accepted ones), Preset field or parameter file."""
        self.selected_rows()
        self.train_config()
        if self.profile.robot is not None:
            self.resolve_robot(self.profile.robot)
        if self.profile.preset_overrides:
            from ..learn.presets import Preset

            known = {f.name for f in fields(Preset)} - {"name"}
            bad = sorted(set(self.profile.preset_overrides) - known)
            if bad:
                raise UsageError(f"profile {self.profile.name!r}: preset_overrides {bad} are not Preset fields")
        if self.profile.params is not None and str(self.profile.params).endswith(".json"):
            from ..description import read_param_file

            read_param_file(self.profile.params)  # missing, malformed or no rigid body: refused before any work

    def preset(self, name: str):
        """The preset a preset row ``name`` trains: its own, or with :attr:`preset_overrides` (a new
        :class:`~hybrid_dyn.learn.presets.Preset`; the name stays, the fields and so the fingerprint change)."""
        if not self.profile.preset_overrides:
            return name
        from ..learn.presets import PRESETS

        return PRESETS.lookup(name).replace(**self.profile.preset_overrides)

    def train_config(self):
        from ..learn import TrainConfig

        # --params is the nominal model: the residual rows' priors sit on it too (identified rows replace it).
        nominal = {"analytic_params": self.profile.params} if self.profile.params is not None else {}
        p = self.profile
        return TrainConfig.recipe(p.recipe, **{"seed": p.seed, **nominal, **p.train})

    def selected_rows(self) -> list[Row]:
        """The rows this profile runs (where they apply), in declaration order."""
        return select_rows(names=self.profile.rows, families=self.profile.families)

    def applies(self, row: Row, ds) -> bool:
        """Whether a row can run on a dataset (:meth:`skip_reason` is None)."""
        return self.skip_reason(row, ds) is None

    def skip_reason(self, row: Row, ds) -> str | None:
        """Why ``row`` does not run on ``ds`` (e.g. "needs base_wrench", "needs a URDF for robot 'x'"),
        or None when it runs: the fields it declares exist, and a URDF where it needs one."""
        only = self.profile.scenario_families.get(ds.meta.get("scenario"))
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
        """``description.resolve_robot`` of ``name`` with the profile's tool (replacing the name's own tool)."""
        from ..description import parse_robot_name, resolve_robot

        if self.profile.tool is None:
            return resolve_robot(name)
        base, _, payload = parse_robot_name(name)
        return resolve_robot(base, tool=self.profile.tool, payload=payload)

    def robot_ref(self, ds):
        """What the analytic model of ``ds`` is: the profile's ``robot``, else the dataset's own, with ``tool``."""
        name = self.profile.robot or ds.meta.get("robot")
        if not name:
            raise DatasetError(f"dataset {ds.path} does not name its robot (manifest key 'robot'); give one (--robot)")
        return self.resolve_robot(name)

    def dataset(self, scenario: str, data_root: Path, log=print, executor=None):
        """The scenario's dataset: a dataset path is read as it is; a simulated scenario is generated once
        and cached by its config hash (real-robot logs: imported once, cached by spec and file checksums)."""
        if is_dataset_path(scenario):
            return load_dataset(scenario)
        from ..data.logs.real_logs import REAL_SETS, real_dataset

        if scenario in REAL_SETS:

            spec = self.profile.scenario_overrides.get(scenario, {})  # e.g. another split of the same log
            return load_dataset(real_dataset(scenario, Path(data_root), log=log, **spec))
        from ..sim.generator import generate_dataset

        cfg = self.scenario_config(scenario)
        path = self.dataset_path(scenario, data_root)
        try:
            return load_dataset(path)
        except DatasetError:
            log(f"[bench] generating {scenario} ({self.profile.generator_size}) into {path}")
            generate_dataset(cfg, path, workers=self.profile.workers, executor=executor)
            return load_dataset(path)

    def dataset_path(self, scenario: str, data_root: Path) -> Path:
        """Where a simulated scenario's dataset is cached: one folder per generator size and config hash."""
        config_hash = self.scenario_config(scenario).config_hash()
        return Path(data_root) / f"{scenario}-{self.profile.generator_size}-{config_hash}"

    def generator_config(self, scenario: str, ds):
        """The generator config that simulated ``ds``: a named scenario's (:meth:`scenario_config`), or for a
        dataset path the config its manifest records (the plant an identification run is recorded on)."""
        if is_dataset_path(scenario):
            from ..sim.generator_config import GeneratorConfig

            return GeneratorConfig.from_dict(ds.meta["config"])
        return self.scenario_config(scenario)

    def scenario_config(self, scenario: str):
        """The generator config of one of the profile's simulated scenarios."""
        from ..sim.scenarios import scenario_config

        p = self.profile
        return scenario_config(scenario, p.generator_size, seed=p.seed,
                               **{**p.generator_overrides, **p.scenario_overrides.get(scenario, {})})


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


@dataclass
class BenchContext:
    """What a row's build sees of its scenario (one per scenario of a run)."""

    profile: object  # profiles.BenchProfile
    scenario: str
    dataset: object  # data.Dataset
    robot: object | None  # the nominal analytic.Robot every analytic part uses (None: no URDF for this arm)
    work_dir: Path
    data_root: Path = Path("data")
    log: Callable[[str], None] = print
    cache: dict = field(default_factory=dict)
    source: str = ""  # the profile's scenario entry (a name, or a dataset path); ``scenario`` is its label

    @property
    def plan(self) -> BenchPlan:
        """What the run does with :attr:`profile`: its training config, presets, datasets."""
        return BenchPlan(self.profile)
