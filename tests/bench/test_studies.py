"""hybrid_dyn.bench.studies and study_summaries: a study is a profile plus overrides declared as data."""
import dataclasses
import json

import pytest

from hybrid_dyn.bench.plan import BenchPlan
from hybrid_dyn.bench import profiles as profiles_mod
from hybrid_dyn.bench.profiles import PROFILES
from hybrid_dyn.bench.runner import run_bench
from hybrid_dyn.bench.studies import BASE, STUDIES, Overrides, Study, StudyRun, run_study
from hybrid_dyn.bench.study_summaries import control_arms
from hybrid_dyn.errors import UsageError


def _changed(a: dict, b: dict) -> set:
    return {k for k in set(a) | set(b) if a.get(k) != b.get(k)}


@pytest.mark.parametrize("name", list(STUDIES))
def test_a_declared_variant_changes_only_what_it_declares(name):
    study = STUDIES[name]
    base = study.base_profile().to_dict()
    for variant, over in study.variants.items():
        prof = study.variant_profile(variant, ("rnea",))
        got = prof.to_dict()
        declared = {"name", "rows", "families", "notes"}  # every variant: its own name, rows and note
        declared |= {"scenarios"} if study.scenarios else set()
        both = over.on_top_of(study.base)
        declared |= {"generator_overrides"} if both.data else set()
        declared |= {"scenario_overrides"} if both.scenario_data else set()
        declared |= {"train"} if both.train else set()
        declared |= {"recipe"} if both.recipe and both.recipe != base["recipe"] else set()
        declared |= {"preset_overrides"} if both.preset else set()
        assert _changed(base, got) <= declared, (variant, _changed(base, got) - declared)
        assert prof.name == f"{base['name']}--{name}-{variant}"
        for k, v in both.train.items():
            assert got["train"][k] == v
        assert prof.notes[-1].startswith(f"Study `{name}`, variant `{variant}`")


def test_overrides_stack_field_by_field_over_the_base():
    base = Overrides(data={"n_instances": 80}, train={"lr": 1e-3}, scenario_data={"s": {"a": 1}})
    top = Overrides(train={"batch_size": 256}, scenario_data={"s": {"b": 2}}, budget_factor=4)
    both = top.on_top_of(base)
    assert both.data == {"n_instances": 80} and both.train == {"lr": 1e-3, "batch_size": 256}
    assert both.scenario_data == {"s": {"a": 1, "b": 2}} and both.budget_factor == 4
    assert Overrides().is_empty() and not both.is_empty()
    assert "budget x4" in both.describe() and "batch_size=256" in both.describe()


def test_a_bad_declaration_is_refused_when_declared():
    with pytest.raises(UsageError, match="one or more variants"):
        Study("s", "seed-sim", "", variants={})
    with pytest.raises(UsageError, match="not 'base'"):
        Study("s", "seed-sim", "", variants={BASE: Overrides()})
    with pytest.raises(UsageError, match="unknown training recipe"):
        Study("s", "seed-sim", "", rows=("rnea",), variants={"v": Overrides(recipe="nope")})
    with pytest.raises(UsageError, match="not Preset fields"):
        Study("s", "seed-sim", "", rows=("rnea",), variants={"v": Overrides(preset={"widht": 3})})
    with pytest.raises(UsageError, match="unknown bench rows"):
        Study("s", "seed-sim", "", rows=("rnea", "rneaa"), variants={"v": Overrides()})
    with pytest.raises(UsageError, match="scenarios"):
        Study("s", "seed-sim", "", rows=("rnea",), variants={"v": Overrides(scenario_data={"paper-ext": {}})})
    with pytest.raises(UsageError, match="name its rows"):  # no report of a changed profile to choose on
        Study("s", "seed-sim", "", base=Overrides(data={"n_instances": 8}), variants={"v": Overrides()})
    with pytest.raises(UsageError, match="summary"):
        Study("s", "seed-sim", "", rows=("rnea",), variants={"v": Overrides()}, summary="nope")


def test_preset_overrides_are_recorded_only_when_set():
    plain = PROFILES.lookup("seed-sim")
    assert "preset_overrides" not in plain.to_dict()  # reports written before the field compare equal
    wide = dataclasses.replace(plain, preset_overrides={"fc_units": 256})
    assert wide.to_dict()["preset_overrides"] == {"fc_units": 256}
    assert BenchPlan(plain).preset("seed-tau-mlp") == "seed-tau-mlp"
    p = BenchPlan(wide).preset("seed-tau-mlp")
    assert p.name == "seed-tau-mlp" and p.fc_units == 256


def test_the_controls_summary_reads_each_variant_against_the_reference_on_validation(tmp_path):
    study = Study("conv", "seed-sim", "does more training pay", rows=("seed-tau-mlp", "delan"),
                  variants={"x2": Overrides(budget_factor=2)}, tolerance=0.03)

    def row(model, val, rmse, status="ok"):
        return {"scenario": "seed-sim", "task": "joint_torque", "model": model, "status": status,
                "val_loss": str(val), "rmse": str(rmse), "nmse": "0.1", "epochs": "40", "stopped_by": "budget"}

    reference = [row("seed-tau-mlp", 0.200, 1.0), row("delan", 0.100, 2.0), row("rnea", 0.5, 3.0)]
    variant = [row("seed-tau-mlp", 0.198, 1.1), row("delan", 0.090, 1.9)]  # -1 % (converged), -10 % (not)
    run = StudyRun(study, tmp_path / "report", reference, ("seed-tau-mlp", "delan"), {}, points={"x2": variant})
    summary = control_arms(run, tmp_path / "out")
    (panel,) = summary["panels"]
    entries = {line["model"]: line["entries"] for line in panel["rows"]}
    assert set(entries) == {"seed-tau-mlp", "delan"}  # rows the study did not rerun are not summarised
    mlp, delan = entries["seed-tau-mlp"][1], entries["delan"][1]
    assert mlp["val_change"] == pytest.approx(-0.01) and mlp["converged"] is True
    assert delan["val_change"] == pytest.approx(-0.10) and delan["converged"] is False
    text = (tmp_path / "out" / "README.md").read_text()
    assert "| delan | x2 | budget x2 | 40 (budget) | 0.09000 | -10.0% | 1.9000 | 0.1000 | NO |" in text
    assert json.loads((tmp_path / "out" / "conv.json").read_text())["tolerance"] == 0.03


@pytest.mark.slow
def test_a_study_changes_presets_and_budgets_through_the_harness(tmp_path, monkeypatch):
    """A capacity variant (a Preset field) and a budget variant (each row's own budget doubled) really train
    what they declare: the saved models say so, and the summary sets them against the profile's report."""
    tiny = dataclasses.replace(
        profiles_mod.PROFILES["quick"], name="tiny-study", families=(), rows=("rnea", "seed-tau-mlp"),
        generator_overrides=dict(n_instances=6, trajectories=(1, 1)), scenario_overrides={},
        train=dict(budget_steps=20, budget_evals=2, batch_size=64), workers=1)
    monkeypatch.setitem(profiles_mod.PROFILES, "tiny-study", tiny)
    study = Study("tiny-controls", "tiny-study", "a test", rows=("seed-tau-mlp",), variants={
        "wide": Overrides(preset={"fc_units": 48}), "longer": Overrides(budget_factor=2)})
    report, data, runs = tmp_path / "report", tmp_path / "data", tmp_path / "runs"
    roots = dict(work_root=runs, data_root=data, log=lambda m: None)
    run_bench(tiny, report, data_root=data, work_root=runs, log=lambda m: None)
    summary = run_study(study, report, tmp_path / "out", **roots)

    configs = {p.parts[len(runs.parts)]: json.loads(p.read_text())
               for p in runs.rglob("models/seed-tau-mlp/config.json")}
    assert configs["tiny-study"]["preset"]["fc_units"] == 32  # the profile's own model
    assert configs["tiny-study--tiny-controls-wide"]["preset"]["fc_units"] == 48
    assert configs["tiny-study--tiny-controls-longer-seed-tau-mlp"]["train_config"]["budget_steps"] == 40
    (panel,) = [p for p in summary["panels"] if p["task"] == "joint_torque"]
    (line,) = panel["rows"]
    assert [e["variant"] for e in line["entries"]] == ["reference", "wide", "longer"]
    assert all(e["status"] == "ok" and e["val_loss"] > 0 for e in line["entries"])
    assert line["entries"][1]["val_loss"] != line["entries"][0]["val_loss"]  # another net, another loss


def test_the_compare_summary_sets_each_variant_report_against_the_reference(tmp_path):
    from hybrid_dyn.bench.study_summaries import compare

    from helpers.bench import written_report

    def report(folder, rnea, mlp):
        written_report(folder, [
            {"task": "joint_torque", "scenario": "paper-noext", "model": m, "family": f, "status": "ok", "rmse": r,
             "val_loss": 0.1, "test_loss": 0.1, "nmse": 0.1, "epochs": "", "best_epoch": ""}
            for m, f, r in (("rnea", "analytic", rnea), ("seed-tau-mlp", "seed-net", mlp))])

    report(tmp_path / "full", 0.25, 1.0)
    report(tmp_path / "out" / "small", 0.5, 5.0)
    study = STUDIES["data-control"]
    run = StudyRun(study, tmp_path / "full", [], ("tau-mlp-wide",), {}, dirs={"small": [tmp_path / "out" / "small"]})
    compare(run, tmp_path / "out")
    text = (tmp_path / "out" / "README.md").read_text()
    assert text.startswith("# Study `data-control` on profile `default`")
    assert "\n## `" in text and "\n### paper-noext, joint torque" in text  # each comparison one level down
    assert "small `rnea` 0.500 Nm, default `rnea` 0.250 Nm" in text
    assert "| seed-tau-mlp | seed-net | 5.000 | 10.00 | - (-) | 1.000 | 4.00 | - (-) | 0.40x |" in text


def test_a_real_sets_scenario_overrides_reach_its_import(monkeypatch, tmp_path):
    from hybrid_dyn.data.logs import real_logs as real_mod

    seen = {}

    def fake_real_dataset(set_name, root, /, log=None, **spec):  # positional-only, as real_dataset's
        seen[set_name] = spec
        raise real_mod.RealLogMissingError(set_name, ["x"])

    monkeypatch.setattr(real_mod, "real_dataset", fake_real_dataset)
    study = STUDIES["interpolation-control"]
    profile = study.variant_profile("chunks", ("gp",))
    with pytest.raises(real_mod.RealLogMissingError):
        BenchPlan(profile).dataset("real-kuka", tmp_path)
    assert seen["real-kuka"] == {"name": "real-kuka-chunks", "trajectories": "blocks", "n_blocks": 4}
    with pytest.raises(real_mod.RealLogMissingError):
        BenchPlan(study.base_profile()).dataset("real-kuka", tmp_path)
    assert seen["real-kuka"] == {}  # the profile itself imports the log as its spec says


def test_a_budget_is_scaled_from_the_preset_a_row_trains():
    from hybrid_dyn.bench.studies import _preset

    profile = PROFILES.lookup("seed-sim")
    assert _preset(profile, "residual-rnea-identified").name == "residual-rnea"  # the identified residual's net
    assert _preset(profile, "seed-tau-mlp").kind == "mlp"
    with pytest.raises(UsageError, match="no step budget"):
        _preset(profile, "gp")


class _Started(Exception):
    """Raised in place of a study's first piece of work: the study got past its output checks."""


def test_study_out_refuses_a_users_folder_before_any_work(tmp_path, monkeypatch, capsys):
    """`study --out DIR` on a folder holding the user's README.md started generating."""
    from hybrid_dyn.bench import studies as studies_mod
    from hybrid_dyn.cli import main as cli_main

    def started(*args, **kwargs):
        raise _Started()

    monkeypatch.setattr(studies_mod, "_run_variant", started)  # "budget" runs its base variant first
    monkeypatch.setattr(studies_mod, "read_full_report", started)
    out = tmp_path / "mine"
    out.mkdir()
    (out / "README.md").write_text("# my notes\n")
    capsys.readouterr()
    assert cli_main(["study", "budget", "--out", str(out), "--work-root", str(tmp_path / "runs"),
                     "--data-root", str(tmp_path / "data")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: refusing to replace") and len(err.splitlines()) == 1, err
    assert str(out) in err and "README.md" in err and "budget.json" in err, err
    assert [p.name for p in out.iterdir()] == ["README.md"] and (out / "README.md").read_text() == "# my notes\n"
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == ["mine"]  # no work began


def test_a_study_writes_its_summary_only_where_it_is_still_its_own(tmp_path, monkeypatch):
    """The summary was written with no ownership check. A folder the study wrote (its
    summary JSON names it) is its own on a rerun; a user's file that appears in a new folder while the
    variants run makes the summary a refusal, and the file stays."""
    from hybrid_dyn.bench import studies as studies_mod
    from hybrid_dyn.errors import OutputPathError

    study, out, late = STUDIES["budget"], tmp_path / "out", tmp_path / "late"

    def variant(study, name, rows, where, reference_report=None, **run_args):
        return [], [where]

    monkeypatch.setattr(studies_mod, "_run_variant", variant)
    args = dict(work_root=tmp_path / "runs", log=lambda m: None)
    for _ in range(2):  # a new folder, then its own
        run_study(study, tmp_path / "report", out, **args)
        assert json.loads((out / "budget.json").read_text())["study"] == "budget" and (out / "README.md").is_file()

    def variant_while_the_user_writes(study, name, rows, where, reference_report=None, **run_args):
        late.mkdir(exist_ok=True)
        (late / "README.md").write_text("# mine, written while the study ran\n")
        return [], [where]

    monkeypatch.setattr(studies_mod, "_run_variant", variant_while_the_user_writes)
    with pytest.raises(OutputPathError, match="refusing to replace .*late: it holds README.md but no budget.json"):
        run_study(study, tmp_path / "report", late, **args)
    assert [p.name for p in late.iterdir()] == ["README.md"]
    assert (late / "README.md").read_text() == "# mine, written while the study ran\n"
