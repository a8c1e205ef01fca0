"""hybrid_dyn.bench.compare (hybrid-dyn compare): two reports, each row against its own report's physics."""
import json

from hybrid_dyn.bench.compare import compare_reports
from hybrid_dyn.bench.results import write_results
from hybrid_dyn.cli import main as cli_main


def _report(folder, rows, overrides=None):
    folder.mkdir()
    (folder / "run.json").write_text(json.dumps({"bench_report": 1, "profile": {"scenario_overrides": overrides or {}}}))
    write_results(folder / "results.csv", [
        {"task": task, "scenario": "s", "model": model, "family": family, "status": "ok", "rmse": rmse,
         "val_loss": 0.1, "test_loss": 0.1, "nmse": 0.1, "epochs": "", "best_epoch": ""}
        for task, model, family, rmse in rows])


def test_rows_only_in_one_report_and_physics_only_scenarios_are_left_out(tmp_path):
    _report(tmp_path / "a", [("joint_torque", "rnea", "analytic", 1.0), ("joint_torque", "delan", "delan", 2.0),
                             ("joint_torque", "seed-tau-mlp", "seed-net", 4.0),
                             ("tip_force", "base-wrench", "analytic", 1.0)])
    _report(tmp_path / "b", [("joint_torque", "rnea", "analytic", 0.5), ("joint_torque", "delan", "delan", 0.5),
                             ("tip_force", "base-wrench", "analytic", 1.0)])
    text = compare_reports(tmp_path / "a", tmp_path / "b", labels=("less", "more"))
    assert "| delan | delan | 2.000 | 2.00 | - (-) | 0.500 | 1.00 | - (-) | 0.50x |" in text
    assert "seed-tau-mlp" not in text  # not in the second report: nothing to compare
    assert "tip force" not in text  # physics rows only: no learned row to set against them
    assert "less `rnea` 1.000 Nm, more `rnea` 0.500 Nm" in text
    assert "the generator's default" in text  # no sizes recorded


def test_compare_refuses_a_folder_that_is_no_report(tmp_path, capsys):
    _report(tmp_path / "a", [("joint_torque", "rnea", "analytic", 1.0)])
    (tmp_path / "empty").mkdir()
    assert cli_main(["compare", str(tmp_path / "a"), str(tmp_path / "empty")]) == 2
    assert "holds no bench report" in capsys.readouterr().err
