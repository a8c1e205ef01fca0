"""Studies: a bench profile run again with overrides declared as data, and what changed.

The design in full: ``docs/design/bench.md`` (studies.py).
"""
from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import UsageError
from ..outputs import json_marker, output_lock, refuse_foreign_files
from ..registry import Registry
from ..resources import resource_dir
from .catalog import ROWS, select_rows
from .integrity import is_bench_meta, read_run_json, same_profile, verify_results
from .plan import BenchPlan
from .families import FAMILIES
from .profiles import PROFILES, BenchProfile, as_tuples
from .results import read_results
from .rows import TASK_TARGET, is_physics_family, is_physics_result

UNITS = {"tip_force": "N", "joint_torque": "Nm"}
BASE = "base"  # the variant name of a study's reference point when it changes the profile (Study.base)


@dataclass(frozen=True)
class Overrides:
    """What a variant changes in the profile (every field optional; see the module's docstring)."""

    data: dict = field(default_factory=dict)  # GeneratorConfig fields, every simulated scenario
    scenario_data: dict = field(default_factory=dict)  # scenario -> GeneratorConfig or import-spec fields
    train: dict = field(default_factory=dict)  # TrainConfig fields (train_instances: fewer training instances)
    recipe: str | None = None  # learn.recipes.RECIPES
    preset: dict = field(default_factory=dict)  # Preset fields of every trained preset row
    budget_factor: float | None = None  # each row's own step budget (budgeted recipe) times this
    rows: tuple = ()  # rerun only these of the study's rows (e.g. a capacity change that means nothing to DeLaN)

    def is_empty(self) -> bool:
        return self == Overrides()

    def on_top_of(self, under: "Overrides") -> "Overrides":
        """These overrides applied after ``under`` (a study's base), field by field."""
        scenario_data = {s: {**under.scenario_data.get(s, {}), **self.scenario_data.get(s, {})}
                         for s in {**under.scenario_data, **self.scenario_data}}
        return Overrides(data={**under.data, **self.data}, scenario_data=scenario_data,
                         train={**under.train, **self.train}, recipe=self.recipe or under.recipe,
                         preset={**under.preset, **self.preset},
                         budget_factor=self.budget_factor or under.budget_factor, rows=self.rows or under.rows)

    def apply(self, profile: BenchProfile, name: str, rows: tuple, families: tuple = (),
              scenarios: tuple = ()) -> BenchProfile:
        """``profile`` renamed, running ``rows`` (and ``families``) on ``scenarios`` (all: empty), changed."""
        scenario_overrides = {s: {**profile.scenario_overrides.get(s, {}), **self.scenario_data.get(s, {})}
                              for s in {**profile.scenario_overrides, **self.scenario_data}}
        return dataclasses.replace(
            profile, name=name, rows=tuple(rows), families=tuple(families),
            scenarios=tuple(scenarios) or profile.scenarios, recipe=self.recipe or profile.recipe,
            train={**profile.train, **self.train}, generator_overrides={**profile.generator_overrides, **self.data},
            scenario_overrides=scenario_overrides, preset_overrides={**profile.preset_overrides, **self.preset})

    def describe(self) -> str:
        """The changes in words, for the summary's tables."""
        parts = [f"{k}={v}" for k, v in self.data.items()]
        parts += [f"{s}: " + ", ".join(f"{k}={v}" for k, v in f.items()) for s, f in self.scenario_data.items()]
        parts += ([f"recipe {self.recipe}"] if self.recipe else []) + [f"{k}={v}" for k, v in self.train.items()]
        parts += [f"preset {k}={v}" for k, v in self.preset.items()]
        parts += [f"budget x{self.budget_factor:g}"] if self.budget_factor else []
        return "; ".join(parts) or "none"


@dataclass(frozen=True)
class Study:
    """A profile plus named variants (:class:`Overrides`), the rows they rerun and the summary it writes.

    train_instances: the data-scaling shorthand, one variant ``train-N`` per size (val cut in
    proportion). rows: row names, or "best" (chosen on the full report's validation loss); families:
    whole families besides ``rows``. scenarios: the profile's scenarios the variants run on (all: empty).
    base: overrides under every variant (then the reference point is run too, as variant ``base``).
    summary: a key of :data:`SUMMARY_KINDS` (default: "data-scaling" with train_instances, else
    "controls"). tolerance: "controls" only; a variant whose validation loss is lower than the
    reference's by less than this share counts as no gain (the convergence check). keep_variant_reports:
    the variants' bench reports go beside the summary (committed) instead of under ``runs/studies``.
    out: where the summary goes by default: ``reports/studies/<name>``, or (data-scaling) a
    folder inside its profile's report, ``reports/<profile>/<name>``, beside the report it extends.
    """

    name: str
    profile: str
    description: str
    train_instances: tuple = ()
    variants: dict = field(default_factory=dict)
    rows: object = "best"
    families: tuple = ()
    scenarios: tuple = ()
    base: Overrides = field(default_factory=Overrides)
    summary: str = ""
    tolerance: float | None = None
    keep_variant_reports: bool = False
    out: str | None = None

    def default_out(self) -> Path:
        """The summary's folder when ``--out`` is not given (:attr:`out`)."""
        return Path(self.out or Path("reports") / "studies" / self.name)

    def __post_init__(self):
        from .study_summaries import SUMMARY_KINDS

        variants = dict(self.variants)
        variants.update({f"train-{int(n)}": Overrides(train={"train_instances": int(n)}) for n in self.train_instances})
        object.__setattr__(self, "variants", variants)
        object.__setattr__(self, "summary", self.summary or ("data-scaling" if self.train_instances else "controls"))
        where = f"study {self.name!r}"
        if not variants or BASE in variants or any("/" in v or not v for v in variants):
            raise UsageError(f"{where}: declare one or more variants, named (not {BASE!r}, no '/')")
        if self.summary not in SUMMARY_KINDS:
            raise UsageError(f"{where}: summary must be one of {', '.join(SUMMARY_KINDS)}, got {self.summary!r}")
        if self.rows == "best" and not self.base.is_empty():
            raise UsageError(f"{where}: rows 'best' are chosen on the profile's own report; a study with a base "
                             "change has none: name its rows")
        if self.rows != "best":
            select_rows(names=tuple(self.rows), families=self.families)  # an unknown row or family is refused now
        profile = self.base_profile()
        unknown = [s for s in (*self.scenarios, *self.base.scenario_data,
                               *(s for v in variants.values() for s in v.scenario_data)) if s not in profile.scenarios]
        if unknown:
            raise UsageError(f"{where}: scenarios {unknown} are not profile {self.profile!r}'s")
        for v in (BASE, *variants):  # a bad recipe, training or preset field is refused at declaration
            self.variant_profile(v, ())

    def base_profile(self) -> BenchProfile:
        """The bench profile this study varies (``profiles.PROFILES``)."""
        return PROFILES.lookup(self.profile)

    def overrides(self, variant: str) -> Overrides:
        """What ``variant`` changes in the profile (the base's changes included)."""
        return self.base if variant == BASE else self.variants[variant].on_top_of(self.base)

    def variant_profile(self, variant: str, rows: tuple, families: tuple = ()) -> BenchProfile:
        """The profile of one variant, running ``rows`` (and ``families``) on the study's scenarios."""
        base = self.base_profile()
        over = self.overrides(variant)
        profile = over.apply(base, f"{base.name}--{self.name}-{variant}", rows, families, self.scenarios)
        # The report of a variant says so (its notes are the profile's, which describe the unchanged data).
        return dataclasses.replace(profile, notes=(*base.notes, f"Study `{self.name}`, variant `{variant}` of "
                                                   f"profile `{base.name}`: {over.describe()}."))


def read_studies(path: Path) -> list[Study]:
    """The studies a TOML file declares (``[studies.NAME]`` tables of :class:`Study` fields, their ``variants``
    and ``base`` tables of :class:`Overrides` fields), each checked as it is made."""
    doc = tomllib.loads(Path(path).read_text())
    studies = []
    for name, declared in doc.get("studies", {}).items():
        declared = as_tuples(declared)
        try:
            variants = {v: Overrides(**o) for v, o in declared.pop("variants", {}).items()}
            base = Overrides(**declared.pop("base", {}))
            studies.append(Study(name=name, variants=variants, base=base, **declared))
        except TypeError as err:  # a field Study or Overrides does not have
            raise UsageError(f"{path}: study {name!r}: {err}") from None
    return studies


STUDIES_FILE = resource_dir("bench") / "studies.toml"
STUDIES = Registry("study", UsageError).register_all(read_studies(STUDIES_FILE))




def _ok(rows) -> list[dict]:
    return [r for r in rows if r.get("status") == "ok" and r.get("val_loss") not in (None, "")]


def choose_rows(full: list[dict]) -> dict:
    """(scenario, task, family) -> the learned row of lowest *validation* loss in the full report, and
    (scenario, task, "physics") -> the physics row of lowest validation loss. Validation, not test: the
    study must not pick its rows on the figures it reports.

    The best physics row may read a sensor a learned row does not (on seed-sim the best torque physics
    row reads the base wrench; the reference study's torque nets read q, qd, qdd). Each learned row is also set
    against the best physics row on no more than its own inputs, under the key
    (scenario, task, "physics on <inputs>"), where that row is another."""
    best = {}
    physics = []
    fitted = FAMILIES.names(fitted=True, in_studies=True)  # a study picks their best trained rows
    for r in _ok(full):
        row = ROWS.lookup(r["model"])
        if row.reference is not None:
            continue
        if row.trains and row.family in fitted:
            key = (r["scenario"], r["task"], row.family)
        elif is_physics_result(r):
            key = (r["scenario"], r["task"], "physics")
            physics.append(r)
        else:
            continue
        if key not in best or float(r["val_loss"]) < float(best[key]["val_loss"]):
            best[key] = r
    for (scenario, task, family), r in list(best.items()):
        if is_physics_family(family):
            continue
        inputs = set(ROWS.lookup(r["model"]).needs)
        same = [p for p in physics if (p["scenario"], p["task"]) == (scenario, task)
                and set(ROWS.lookup(p["model"]).needs) <= inputs]
        if same:
            fair = min(same, key=lambda p: float(p["val_loss"]))
            if fair["model"] != best[(scenario, task, "physics")]["model"]:
                target = TASK_TARGET[task]
                label = "physics on " + ", ".join(f for f in ROWS.lookup(fair["model"]).needs if f != target)
                best.setdefault((scenario, task, label), fair)
    return best


def read_full_report(study: Study, report: Path) -> list[dict]:
    """The profile's own report: the study's reference point. Refused unless it is a report of that profile."""
    meta = read_run_json(report)
    if meta is None or not (report / "results.csv").is_file():
        raise UsageError(f"{report} holds no bench report; run `hybrid-dyn bench --profile {study.profile} "
                         f"--out {report}` first (the study's full-data point)")
    if not same_profile(meta["profile"], study.base_profile()):
        raise UsageError(f"{report} is a report of another profile or size than {study.profile!r}: rerun the bench")
    rows = read_results(report / "results.csv")
    verify_results(rows, meta, None, report)  # rows the bench wrote for this profile, not edited since
    return rows


@dataclass
class StudyRun:
    """What a summary is written from: the reference point and every variant's results."""

    study: Study
    report: Path  # the reference point's report folder (the profile's own, or the variant ``base``'s)
    reference: list  # its results.csv rows (on the study's scenarios)
    rows: tuple  # the rows the variants reran
    chosen: dict  # rows "best": choose_rows of the reference; else {}
    points: dict = field(default_factory=dict)  # variant -> its results rows
    dirs: dict = field(default_factory=dict)  # variant -> its report folders

    def train_instances(self) -> int:
        """How many training instances the reference point's models saw (:func:`train_instances_of`)."""
        return train_instances_of(self.report, self.study.scenarios)


def run_study(study: Study, report: Path, out: Path, work_root: Path = Path("runs"), data_root=None,
              executor=None, log=print) -> dict:
    """Run every variant through the harness (resumable: each is a bench report), then write the summary
    to ``out`` (:data:`SUMMARY_KINDS`); returns the summary's data. ``report``: the profile's own report
    (the reference point; not read for a study with a ``base`` change, whose reference is run here)."""
    from .study_summaries import SUMMARY_KINDS

    out, report = Path(out), Path(report)
    with output_lock(out, "study summary folder"):  # one study per summary folder at a time
        check_study_dir(out, study)  # a user's folder is refused before any work, as bench --out refuses
        run = _run_variants(study, report, out, work_root, data_root, executor, log)
        check_study_dir(out, study)  # and the summary is written only where it is still the study's own
        return SUMMARY_KINDS[study.summary](run, out)


def summary_file(study: Study) -> str:
    """The summary's JSON, also the mark of the study's folder (its ``"study"`` is the study's name)."""
    return "data_scaling.json" if study.summary == "data-scaling" else f"{study.name}.json"


def check_study_dir(out: Path, study: Study) -> None:
    """Refuse ``out`` unless it is new, empty, or the study's own: its summary JSON (:func:`summary_file`)
    names the study, or (a study stopped before its summary) it holds only the variants' bench reports
    kept beside the summary and their locks."""
    out = Path(out)
    if out.is_dir() and json_marker(out / summary_file(study), "study", study.name) is not None:
        return

    def is_own(p: Path) -> bool:
        if p.name.startswith(".") and p.name.endswith(".lock"):
            return True
        return p.name in (BASE, *study.variants) and is_bench_meta(json_marker(p / "run.json", "bench_report", 1))

    refuse_foreign_files(out, "study summary folder", is_own, marker=summary_file(study))


def _run_variants(study: Study, report: Path, out: Path, work_root, data_root, executor, log) -> "StudyRun":
    """The reference point and every variant's bench (each resumable: a bench report): the summary's input."""
    variant_root = out if study.keep_variant_reports else Path(work_root) / "studies" / study.name
    run_args = dict(data_root=data_root, work_root=work_root, executor=executor, log=log)
    if study.base.is_empty():
        reference = read_full_report(study, report)
    else:
        report = variant_root / BASE
        reference = _run_variant(study, BASE, _named_rows(study), report, **run_args)[0]
    if study.scenarios:
        reference = [r for r in reference if r["scenario"] in study.scenarios]
    chosen = choose_rows(reference) if study.rows == "best" else {}
    rows = tuple(dict.fromkeys(r["model"] for k, r in chosen.items() if not is_physics_family(k[2]))) if chosen \
        else _named_rows(study)
    if study.rows != "best" and study.base.is_empty():
        missing = [r for r in study.rows if r not in {x["model"] for x in reference}]
        if missing:
            raise UsageError(f"study {study.name}: rows {missing} are not in {report}: run them in the bench first")
    run = StudyRun(study, report, reference, rows, chosen)
    for variant in study.variants:
        log(f"[study] {study.name}: variant {variant} ({study.variants[variant].describe()})")
        run.points[variant], run.dirs[variant] = _run_variant(study, variant, rows, variant_root / variant,
                                                              reference_report=report, **run_args)
    return run


def _named_rows(study: Study) -> tuple:
    return () if study.rows == "best" else tuple(study.rows)


def _run_variant(study: Study, variant: str, rows: tuple, where: Path, reference_report: Path | None = None,
                 **run_args) -> tuple[list, list]:
    """One variant's bench (one per row when it scales each row's budget): (its results rows, its folders)."""
    from .runner import run_bench

    over = study.overrides(variant)
    only = [r for r in rows if not over.rows or r in over.rows]
    if "train_instances" in over.train and reference_report is not None:
        n, n_train = over.train["train_instances"], train_instances_of(reference_report, study.scenarios)
        if n >= n_train:
            raise UsageError(f"study {study.name}: {n} training instances asked for, the full report trained on "
                             f"{n_train}")
    if not over.budget_factor:
        profile = study.variant_profile(variant, tuple(only), study.families)
        return run_bench(profile, where, **run_args), [where]
    results, dirs = [], []
    for row in only:  # each row's own budget, scaled: one bench per row
        profile = study.variant_profile(variant, (row,))
        budget = BenchPlan(profile).train_config().for_preset(_preset(profile, row)).budget_steps
        if budget is None:
            raise UsageError(f"study {study.name}: budget_factor needs the budgeted recipe (profile {study.profile!r}"
                             f" trains {row} under {profile.recipe!r})")
        steps = max(1, round(budget * over.budget_factor))
        profile = dataclasses.replace(profile, name=f"{profile.name}-{row}",
                                      train={**profile.train, "budget_steps": steps})
        results += run_bench(profile, where / row, **run_args)
        dirs.append(where / row)
    return results, dirs


def _preset(profile: BenchProfile, row: str):
    """The preset a row trains (a residual on the identified model: its preset), for its step budget."""
    from ..learn.presets import PRESETS
    from .identified_rows import RESIDUAL_ROWS

    name = RESIDUAL_ROWS.get(row, row)
    if name not in PRESETS:  # a preset's row, trained by the runner
        raise UsageError(f"row {row!r} trains no network preset: it has no step budget to scale (budget_factor)")
    preset = BenchPlan(profile).preset(name)
    return PRESETS.lookup(preset) if isinstance(preset, str) else preset


def train_instances_of(report: Path, scenarios: tuple = ()) -> int:
    """How many training instances the report's models saw: its dataset's train split (the smallest of
    its datasets, or of those of ``scenarios``)."""
    from ..data import load_dataset

    datasets = {s: d for s, d in (read_run_json(report).get("datasets") or {}).items()
                if not scenarios or s in scenarios}
    if not datasets:
        raise UsageError(f"{report} records no dataset{' of ' + ', '.join(scenarios) if scenarios else ''}")
    return min(len(load_dataset(info["path"]).split("train")) for info in datasets.values())
