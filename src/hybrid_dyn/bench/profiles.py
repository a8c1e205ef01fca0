"""Benchmark profiles: which scenarios, which rows, how long to train.

quick    every family on one small scenario (``make demo``), minutes on 2 cores
default  every row on paper-noext, paper-ext and mismatch-ext; the analytic rows on contact-steps (1 kHz)
paper    the study's scale (1000 instances per scenario)
real     the joint-torque models that need no URDF on the three real-robot logs
         (KUKA and Baxter split by trajectory; SARCOS, one test file of 4,449
         rows, split by contiguous blocks: see benchmarks/real/sarcos.toml)
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..data import DatasetError, load_dataset
from ..errors import UsageError
from .catalog import select_rows
from .rows import Row

# Every family but the other black-box nets (tau-mlp-wide is for small real sets).
STUDY_FAMILIES = ("analytic", "seed-net", "residual", "delan", "identified")


@dataclass(frozen=True)
class BenchProfile:
    """A benchmark: scenarios, the rows to run on them, how to train.

    Rows are named by family (``families``, keys of ``rows.FAMILIES``) and by name
    (``rows``, rows declared in ``rows.ROWS``); they run in declaration order, each
    where it applies (:meth:`applies`).
    """

    name: str
    scenarios: tuple
    generator_profile: str = "quick"
    families: tuple = STUDY_FAMILIES
    rows: tuple = ()
    recipe: str = "default"  # learn.train.RECIPES
    train: dict = field(default_factory=dict)  # TrainConfig fields on top of the recipe
    generator_overrides: dict = field(default_factory=dict)  # GeneratorConfig fields, every scenario
    scenario_overrides: dict = field(default_factory=dict)  # scenario -> GeneratorConfig fields, that one only
    workers: int = 2
    torch_threads: int = 1  # see runner.run_bench: one thread is fastest for these nets
    notes: tuple = ()  # method notes printed in the report (fixed before any result)
    # Scenarios that run only some families (scenario -> families); the rest run every row.
    scenario_families: dict = field(default_factory=dict)
    seed: int = 0

    def __post_init__(self):
        self.selected_rows()  # an unknown row or family is refused now, not after the data are made

    def train_config(self):
        from ..learn import TrainConfig

        return TrainConfig.recipe(self.recipe, **{"seed": self.seed, **self.train})

    def selected_rows(self) -> list[Row]:
        """The rows this profile runs (where they apply), in declaration order."""
        return select_rows(names=self.rows, families=self.families)

    def applies(self, row: Row, ds) -> bool:
        """Whether a row can run on a dataset: the fields it declares exist, and a URDF where it needs one."""
        only = self.scenario_families.get(ds.meta.get("scenario"))
        if only is not None and row.family not in only:
            return False
        config = ds.meta.get("config", {})
        if row.task == "tip_force" and "pulses" in config and config["pulses"] is None \
                and config.get("contact_steps") is None:
            return False  # no external force in this scenario: nothing to estimate at the tip
        needs = set(row.needs) | set(row.more_needs(ds) if row.more_needs else ())
        return needs <= set(ds.fields) and (not row.needs_urdf or _has_robot(ds))

    def dataset(self, scenario: str, data_root: Path, log=print):
        """The scenario's dataset, generated once and cached by its config hash
        (real-robot logs: imported once, cached by spec and file checksums)."""
        if scenario.startswith("real-"):
            from ..data.real import real_dataset

            return load_dataset(real_dataset(scenario, Path(data_root), log=log))
        from ..sim.generator import generate_dataset

        cfg = self.scenario_config(scenario)
        path = Path(data_root) / f"{scenario}-{self.generator_profile}-{cfg.config_hash()}"
        try:
            return load_dataset(path)
        except DatasetError:
            log(f"[bench] generating {scenario} ({self.generator_profile}) into {path}")
            generate_dataset(cfg, path, workers=self.workers)
            return load_dataset(path)

    def scenario_config(self, scenario: str):
        """The generator config of one of this profile's simulated scenarios."""
        from ..sim.scenarios import scenario_config

        return scenario_config(scenario, self.generator_profile, seed=self.seed,
                               **{**self.generator_overrides, **self.scenario_overrides.get(scenario, {})})

    def to_dict(self) -> dict:
        return asdict(self)


def _has_robot(ds) -> bool:
    from ..description import available_robots

    return ds.meta.get("robot") in available_robots()


PROFILES = {
    "quick": BenchProfile(
        name="quick", scenarios=("mismatch-ext",), generator_profile="quick",
        train=dict(max_epochs=8, batch_size=256, patience=5),
    ),
    # Full epochs and the default recipe (issue 14). To train every model of three scenarios within
    # 120 minutes on 2 cores the data are shrunk, never the training: 28 instances of 5-10
    # trajectories instead of the generator's default 40 of 5-20 (about 0.42 of its samples).
    "default": BenchProfile(
        name="default", scenarios=("paper-noext", "paper-ext", "mismatch-ext", "contact-steps"),
        generator_profile="default",
        train=dict(max_epochs=200),
        scenario_overrides={s: dict(n_instances=28, trajectories=(5, 10))
                            for s in ("paper-noext", "paper-ext", "mismatch-ext")},
        # contact-steps (1 kHz) tests the physics estimators on steps; the nets' windows are
        # counted in samples and were sized for 100 Hz, so they are not trained on it.
        scenario_families={"contact-steps": ("analytic",)},
        notes=("Training: the default recipe on full epochs (Adam 1e-3, reduce-on-plateau x0.3 after 3 epochs down "
               "to 1e-5, early stopping with patience 10, LSTM gradient norm clipped at 1, batch 256, at most 200 "
               "epochs). The seed's recipe (constant rate, patience 5) is `--recipe seed`.",
               "Data: paper-noext, paper-ext and mismatch-ext hold 28 instances of 5-10 trajectories (the generator's "
               "default is 40 of 5-20), so that the whole bench trains within 120 minutes on 2 cores; the data were "
               "shrunk, never the training.",
               "Sequence models are scored on every sample: the first L-1 windows of each instance are edge-padded "
               "with its first sample, as a streaming estimator starts up; all rows see the same test samples.",
               "paper-noext has no external force: its tip-force rows are not run.",
               "contact-steps: step and trapezoid contacts (rise 1-20 ms, plateaus 0.3-1.5 s, 3-25 N) recorded at "
               "1 kHz, the rate of a control loop; only the analytic rows run on it (the nets' windows are counted "
               "in samples and sized for 100 Hz)."),
    ),
    # Real logs carry no base wrench or tip force and no URDF ships for these arms:
    # only the joint-torque models that need neither (PROTOCOL 2, issue 8).
    "real": BenchProfile(
        name="real", scenarios=("real-kuka", "real-baxter", "real-sarcos"), generator_profile="real",
        families=(), rows=("seed-tau-mlp", "seed-tau-conv", "seed-tau-lstm", "seed-tau-lstm-opt", "tau-mlp-wide",
                           "delan", "delan-friction"),
        # Patience 25: the validation trajectories lie partly outside the training range, so
        # validation loss is noisy and the seed's patience of 5 stops after a handful of epochs.
        train=dict(max_epochs=300, batch_size=256, patience=25),
        notes=("KUKA and Baxter: one instance per logged trajectory (10 each), split by trajectory 6/2/2; "
               "SARCOS: its 4,449-row test file is not one continuous trajectory, so it is cut into 10 contiguous "
               "blocks, split 6/2/2 (benchmarks/real/*.toml).",
               "Accelerations: KUKA and Baxter by a zero-phase 5 Hz Butterworth derivative of the logged velocity; "
               "SARCOS: logged. Target: the logged joint torque.",
               "nMSE = per-joint test MSE / per-joint test-target variance, averaged over joints.",
               "Training: up to 300 epochs, patience 25 (validation trajectories lie partly outside the training "
               "range, so the seed's patience of 5 stopped after a handful of epochs). `tau-mlp-wide` (2 x 128, "
               "dropout 0.2) is not a seed model: it was chosen on the validation split for these small sets."),
    ),
    # The seed's own data conditions (its 3.1): 20 Hz, exact states, no sensor noise or bias.
    "seed-sim": BenchProfile(
        name="seed-sim", scenarios=("seed-sim",), generator_profile="default",
        notes=("seed-sim reproduces the seed's data conditions (its section 3.1): recorded every 50 ms (20 Hz), "
               "q, qd, qdd exact from the simulator, no sensor noise and no bias, the same bell pulses and "
               "trajectory rules, 5-50 trajectories per instance.",
               "Training: the default recipe (Adam 1e-3, reduce-on-plateau x0.3 after 3 epochs down to 1e-5, "
               "early stopping with patience 10, LSTM gradient norm clipped at 1, batch 256, full epochs). The "
               "seed's recipe (constant rate, patience 5) is `--recipe seed`.",
               "Sequence models are scored on every sample: the first L-1 windows of each instance are edge-padded "
               "with its first sample, as a streaming estimator starts up; all rows see the same test samples."),
    ),
    "paper": BenchProfile(
        name="paper", scenarios=("paper-noext", "paper-ext", "mismatch-ext"), generator_profile="paper",
        train=dict(max_epochs=200, batch_size=256, patience=5),
    ),
}


def get_profile(name: str) -> BenchProfile:
    if name not in PROFILES:
        raise UsageError(f"unknown bench profile {name!r}; known: {', '.join(PROFILES)}")
    return PROFILES[name]
