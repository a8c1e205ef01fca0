"""Benchmark profiles: which scenarios, which rows, how long to train.

quick    every family on one small scenario (``make demo``), minutes on 2 cores
default  every row on paper-noext, paper-ext and mismatch-ext; the analytic rows on contact-steps (1 kHz),
         contact-steps-quiet (its base sensor at 0.05 N) and contact-steps-hardware (hardware sensors)
paper    the study's scale (1000 instances per scenario)
real     the joint-torque models that need no URDF on the three real-robot logs
         (KUKA and Baxter split by trajectory; SARCOS, one test file of 4,449
         rows, split by contiguous blocks: see src/hybrid_dyn/resources/real/sarcos.toml)

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
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

from ..data import DatasetError, load_dataset
from ..deprecation import renamed_field
from ..errors import UsageError
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


# The method note of every profile under the budgeted recipe (one text, so that it names the recipes
# as learn/recipes.py does; run.json's identity leaves notes out, integrity.same_profile).
BUDGET_RECIPE_NOTE = (
    "Training: the budgeted recipe (learn/recipes.py, docs/models.md): a fixed number of Adam steps per network "
    "kind, batch 1024, lr 2e-3 with a 5 % linear warm-up and a cosine decay to zero, the best of 40 validation "
    "rounds kept; the cost of a row does not grow with the data. The epoch recipe with patience is "
    "`--recipe plateau`, the seed's (constant rate, patience 5) `--recipe seed-study`.")


PROFILES = {
    # make demo: one net of each architecture and family, trained long enough to learn (within
    # about 5 minutes on 2 cores), on a quick mismatch-ext of 30 instances of 5 trajectories. The
    # torque nets are data-limited (reports/studies/data-control): at 12 instances they learned nothing.
    "quick": BenchProfile(
        name="quick", scenarios=("mismatch-ext",), generator_size="quick",
        # The identified rows without their residual nets (those train after the others, one at a time).
        families=("analytic",),
        rows=("seed-tip-2", "seed-tip-5", "seed-tip-8", "residual-basewrench", "residual-base-momentum",
              "seed-tau-mlp", "seed-tau-lstm", "residual-rnea", "delan-friction",
              "identified-ols", "identified-consistent", "identified-sigmoid-friction", "rnea+identified-friction",
              "base-wrench-identified", "base-wrench-identified-tared", "identified-bw-tared"),
        # A demo's budget: 600 steps of 1024 (about 10 passes over its training set), 20 validation rounds.
        train=dict(budget_steps=600, budget_evals=20),
        scenario_overrides={"mismatch-ext": dict(n_instances=30)},
        notes=("A demo: one seed net of each architecture (MLP #2, conv #5, LSTM #8, and the torque MLP and LSTM), "
               "the residual nets and DeLaN with friction, on a small mismatch-ext (30 instances of 5 trajectories); "
               "the budgeted recipe at 600 steps of batch 1024 per net. The black-box "
               "torque nets are data-limited at this size (reports/studies/data-control). The comparisons are in "
               "reports/default and reports/seed-sim.",),
    ),
    # Every row on three simulated scenarios (issue 14) under the budgeted recipe (issue 31): a row
    # costs its step budget whatever the data, so the data grew 3x over the epoch-recipe bench's 40
    # instances of 5-10 trajectories (74.2 min from empty caches), whose learned rows were
    # data-limited (reports/studies/data-control: their RMSE ratios fell with every instance added).
    "default": BenchProfile(
        name="default", scenarios=("paper-noext", "paper-ext", "mismatch-ext", "contact-steps", "contact-steps-quiet",
                                   "contact-steps-hardware"),
        generator_size="default",
        # tau-mlp-wide (2 x 128, dropout 0.2): the larger-capacity control of the seed torque nets.
        rows=("tau-mlp-wide",),
        scenario_overrides={s: dict(n_instances=120, trajectories=(5, 10))
                            for s in ("paper-noext", "paper-ext", "mismatch-ext")},
        # contact-steps (1 kHz) tests the physics estimators on steps; the nets' windows are
        # counted in samples and were sized for 100 Hz, so they are not trained on it.
        scenario_families={"contact-steps": ("analytic",), "contact-steps-quiet": ("analytic",),
                           "contact-steps-hardware": ("analytic",)},
        notes=(BUDGET_RECIPE_NOTE,
               "Data: paper-noext, paper-ext and mismatch-ext hold 120 instances of 5-10 trajectories each (split "
               "by instance 77/19/24), 3x the epoch-recipe bench's 40: under the budget a row's training cost does "
               "not grow with the data.",
               "Sequence models are scored on every sample: the first L-1 windows of each instance are edge-padded "
               "with its first sample, as a streaming estimator starts up; all rows see the same test samples.",
               "paper-noext has no external force: its tip-force rows are not run.",
               "contact-steps: step and trapezoid contacts (rise 1-20 ms, plateaus 0.3-1.5 s, 3-25 N) recorded at "
               "1 kHz, the rate of a control loop; only the analytic rows run on it (the nets' windows are counted "
               "in samples and sized for 100 Hz). contact-steps-quiet: the same with the base sensor at 0.05 N "
               "(0.0025 Nm) noise, where the estimators' automatic bandwidth must change. contact-steps-hardware: the "
               "same contacts read by hardware sensors (q quantized to 1e-5 rad, qd its difference, 0.2 ms stamp "
               "jitter, a 0.025 N/s base-sensor drift, a touch inside the first 0.5 s in a third of the instances; "
               "issue 38), analytic rows only, with the error bar's coverage (sigma_coverage)."),
    ),
    # Real logs carry no base wrench or tip force and no URDF ships for these arms:
    # only the joint-torque models that need neither (PROTOCOL 2, issue 8).
    "real": BenchProfile(
        name="real", scenarios=("real-panda", "real-kuka", "real-baxter", "real-sarcos"), generator_size="real",
        # Physics where a URDF is (the real Panda, bare flange: analytic, identified on the log, residuals
        # on the nominal and the identified model); the black-box rows and the GP everywhere.
        families=("analytic", "identified"),
        rows=("residual-rnea", "seed-tau-mlp", "seed-tau-conv", "seed-tau-lstm", "seed-tau-lstm-opt", "tau-mlp-wide",
              "delan", "delan-friction", "gp"),
        # The budgeted recipe, as every other profile (issues 26, 29). The epoch recipe this profile had
        # (patience 25 at a constant rate, up to 300 epochs) stopped 4 rows by the epoch cap: the
        # validation trajectories lie partly outside the training range, so the validation loss first
        # rises and falls only after tens to hundreds of epochs (KUKA's tau-mlp-wide: 236 epochs). A
        # budget runs every row to its full step count (hundreds of passes over these small sets) and
        # keeps the best of 40 validation rounds, which needs no patience to ride out that rise.
        notes=("Panda (Gaz et al. 2019's exciting trajectory, ../shared/data/real or $HYBRID_DYN_REAL_LOGS; the arm "
               "carried no hand, so the analytic model is panda[tool=none]): the log cut into 10 contiguous time "
               "blocks, split in time order: the first 6 train, the next 2 validate, the last 2 test (60/20/20 of "
               "its 21 s; src/hybrid_dyn/resources/real/panda.toml): every row is scored on the log's last 4.1 s, after all it "
               "was fitted on; identified rows fit on its train and val blocks.",
               "KUKA and Baxter: one instance per logged trajectory (10 each), split by trajectory 6/2/2; "
               "SARCOS: its 4,449-row test file is not one continuous trajectory, so it is cut into 10 contiguous "
               "blocks, split 6/2/2 (src/hybrid_dyn/resources/real/*.toml).",
               "Accelerations: KUKA and Baxter by a zero-phase 5 Hz Butterworth derivative of the logged velocity; "
               "SARCOS: logged. Target: the logged joint torque.",
               "nMSE = per-joint test MSE / per-joint test-target variance, averaged over joints.",
               "Training: the budgeted recipe (a fixed number of Adam steps per network kind, batch 1024, a cosine "
               "decay, the best of 40 validation rounds kept): validation trajectories lie partly outside the "
               "training range, and the validation loss first rises and falls only after tens to hundreds of "
               "passes, which the best-of-rounds rule rides out without a patience. `tau-mlp-wide` (2 x 128, "
               "dropout 0.2) is not a seed model: it was chosen on the validation split for these small sets.",
               "gp: one exact Gaussian process per joint (ARD RBF + white noise, hyperparameters by marginal "
               "likelihood on 600 training rows, conditioned on at most 8000), learn/gp.py. gp-residual-identified "
               "(the Panda): a sparse GP per joint (2000 inducing inputs) on the residual of identified-consistent, "
               "its hyperparameters by marginal likelihood on train and chosen on val, learn/gp_residual.py.",
               "Hybrid rows keep their physics prior where their correction does not beat it on validation; the "
               "section 'Hybrid rows against their physics prior' says where they did."),
    ),
    # The seed's own data conditions (its 3.1): 20 Hz, exact states, no sensor noise or bias.
    "seed-sim": BenchProfile(
        # The seed's size (issue 31): 1000 instances of 5-50 trajectories, split 640/160/200 by instance.
        name="seed-sim", scenarios=("seed-sim",), generator_size="paper",
        notes=("seed-sim reproduces the seed's data conditions (its section 3.1): recorded every 50 ms (20 Hz), "
               "q, qd, qdd exact from the simulator, no sensor noise and no bias, the same bell pulses and "
               "trajectory rules, 5-50 trajectories per instance, at the seed's size: 1000 instances split by "
               "instance 640 train, 160 validation, 200 test (the seed: 3,919,800 samples).",
               BUDGET_RECIPE_NOTE,
               "Sequence models are scored on every sample: the first L-1 windows of each instance are edge-padded "
               "with its first sample, as a streaming estimator starts up; all rows see the same test samples."),
    ),
    "paper": BenchProfile(
        name="paper", scenarios=("paper-noext", "paper-ext", "mismatch-ext"), generator_size="paper",
        recipe="plateau", train=dict(max_epochs=200, batch_size=256, patience=5),
    ),
}


def get_profile(name: str) -> BenchProfile:
    if name not in PROFILES:
        raise UsageError(f"unknown bench profile {name!r}; known: {', '.join(PROFILES)}")
    return PROFILES[name]


# STUDY_FAMILIES: the tuple kept by hand before the families carried their metadata.
__getattr__ = derived_names(__name__, {"STUDY_FAMILIES": ("hybrid_dyn.bench.rows.study_families()", study_families)})
