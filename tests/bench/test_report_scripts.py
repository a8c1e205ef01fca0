"""What reads bench reports: checks/acceptance.py (the project's floors, a script loaded by file path)
and ``hybrid-dyn compare`` (two reports compared through their analytic rows)."""
from __future__ import annotations

import importlib.util
import json

from hybrid_dyn.cli import main as cli_main

from helpers import REPO


def load_script(name: str):
    """checks/NAME.py as a module (the scripts are not part of the package)."""
    spec = importlib.util.spec_from_file_location(name, REPO / "checks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_acceptance_floors_are_a_benchmark_of_their_own(tmp_path, capsys):
    """checks/acceptance.py prints each floor with its numbers and met / NOT met; the report does not."""
    from hybrid_dyn.bench.report import write_report
    from hybrid_dyn.bench.results import read_results, write_results

    def row(scenario, model, family, rmse, rmse_free):
        return {"task": "joint_torque", "scenario": scenario, "model": model, "family": family, "status": "ok",
                "rmse": rmse, "rmse_free": rmse_free, "val_loss": 0.1, "test_loss": 0.1, "nmse": 0.1}

    write_results(tmp_path / "results.csv", [
        row("mismatch-ext", "rnea", "analytic", 2.0, 1.0),
        row("mismatch-ext", "identified-consistent", "identified", 1.2, 0.4),  # 0.6 (NOT met), 0.4 (met)
        row("real-panda", "rnea", "analytic", 1.6, 1.6),
        row("real-panda", "identified-consistent", "identified", 0.32, 0.32),  # 0.2 <= 0.4
        row("real-panda", "residual-rnea-identified", "identified", 0.288, 0.288)])  # 0.9 <= 1.0
    assert load_script("acceptance").main(["--report", str(tmp_path)]) == 1  # one floor is not met
    out = capsys.readouterr().out

    def floor(*words):
        """The verdict and the line of the one floor whose line holds every word."""
        lines = [ln for ln in out.splitlines() if ln.startswith("- ") and all(w in ln for w in words)]
        assert len(lines) == 1, (words, out)
        return lines[0][2:].split(":", 1)[0], lines[0]

    # Each floor: its verdict, the rows compared, their RMSE and the ratio against the floor.
    verdict, line = floor("mismatch-ext", "all samples")
    assert verdict == "NOT met" and "<= 0.5 x" in line
    assert all(n in line for n in ("identified-consistent 1.2000 Nm", "rnea 2.0000 Nm", "= 0.600"))
    verdict, line = floor("mismatch-ext", "free motion")
    assert verdict == "met" and "= 0.400" in line
    verdict, line = floor("real-panda", "identified-consistent <= 0.4 x")
    assert verdict == "met" and "= 0.200" in line
    verdict, line = floor("real-panda", "best residual")
    assert verdict == "met" and "<= 1.0 x" in line
    assert all(n in line for n in ("residual-rnea-identified 0.2880 Nm", "identified-consistent 0.3200 Nm", "= 0.900"))
    (tmp_path / "run.json").write_text(json.dumps({"bench_report": 1, "profile": {"name": "t"}}))
    write_report(tmp_path, read_results(tmp_path / "results.csv"), {"profile": {"name": "t"}, "wall_seconds": 1.0},
                 log=lambda m: None)
    readme = (tmp_path / "README.md").read_text()
    assert "## Floors" not in readme and "NOT met" not in readme and "- met:" not in readme
    assert "identified (identified-consistent) 1.200" in readme  # the findings stay


def test_a_row_stopped_by_its_step_budget_is_never_counted_as_converged():
    """The convergence floor (stopped by patience or lr-floor, not the epoch cap) says nothing of a budgeted
    row, which stops at its budget whether or not it converged: such rows get no verdict."""
    checks = load_script("acceptance")

    def verdicts(*stops):
        rows = [{"task": "joint_torque", "scenario": "s", "model": f"m{i}", "family": "seed-net", "status": "ok",
                 "rmse": 1.0, "stopped_by": stop} for i, stop in enumerate(stops)]
        return {text.split(" (")[0].split(",")[0].split(": ")[-1]: met for text, met, _ in checks.floor_checks(rows)}

    converged = "every learned row stopped by patience or lr-floor"
    budgeted = "(no floor) learned rows trained to their step budget"
    assert verdicts("budget", "budget") == {budgeted: None}
    assert verdicts("budget", "epoch-cap") == {converged: False, budgeted: None}
    assert verdicts("patience", "lr-floor") == {converged: True}


def test_the_data_control_divides_each_learned_row_by_its_own_reports_physics(tmp_path, capsys):
    """hybrid-dyn compare: two reports on different test instances compare through their analytic rows."""
    from helpers.bench import written_report

    def row(model, family, rmse, epochs=""):
        return {"task": "joint_torque", "scenario": "paper-noext", "model": model, "family": family, "status": "ok",
                "rmse": rmse, "val_loss": 0.1, "test_loss": 0.1, "nmse": 0.1, "epochs": epochs, "best_epoch": ""}

    for name, rnea, mlp in (("small", 0.5, 5.0), ("large", 0.25, 1.0)):
        written_report(tmp_path / name, [row("rnea", "analytic", rnea), row("rnea-bw", "analytic", 9.0),
                                         row("seed-tau-mlp", "seed-net", mlp, 12)],
                       profile={"scenario_overrides": {"paper-noext": {"n_instances": 10 if name == "small" else 40,
                                                                       "trajectories": [5, 10]}}})
    assert cli_main(["compare", str(tmp_path / "small"), str(tmp_path / "large")]) == 0
    out = capsys.readouterr().out
    assert "small `rnea` 0.500 Nm, large `rnea` 0.250 Nm" in out  # the best analytic row of each report
    assert "| seed-tau-mlp | seed-net | 5.000 | 10.00 | 12 (-) | 1.000 | 4.00 | 12 (-) | 0.40x |" in out
    assert "10 x (5, 10)" in out and "40 x (5, 10)" in out


def test_the_wall_time_floor_sums_recorded_invocations_and_never_certifies_an_unrecorded_one(tmp_path):
    """The wall-time floor: the sum of the invocations run.json recorded as they ran; a run.json of before
    that (a killed part left no time) is NOT verified, whatever its one number says."""
    checks = load_script("acceptance")

    def verdicts(invocations):
        (tmp_path / "run.json").write_text(json.dumps({"bench_report": 1, "profile": {"name": "default"},
                                                       "invocations": invocations}))
        return {text: (met, nums) for text, met, nums in checks.report_checks(tmp_path)}

    (wall,) = verdicts([{"started": "a", "finished": None, "wall_seconds": 3600, "cold_start": True},
                        {"started": "b", "finished": "c", "wall_seconds": 3000, "cold_start": False}]).values()
    assert wall == (True, "110.0 min over 2 invocation(s), as run.json recorded them while they ran, the first "
                          "from empty caches")
    (wall,) = verdicts([{"started": "a", "finished": None, "wall_seconds": 4000, "cold_start": True},
                        {"started": "b", "finished": "c", "wall_seconds": 3300, "cold_start": False}]).values()
    assert wall[0] is False  # 121.7 min > 120
    (wall,) = verdicts([{"started": "b", "finished": "c", "wall_seconds": 60, "cold_start": False}]).values()
    assert wall[0] == checks.UNVERIFIED  # 1 min, on caches an earlier (dropped) run filled
    (wall,) = verdicts([{"finished": "c", "wall_seconds": 60}]).values()  # 1 min, but not recorded as it ran
    assert wall[0] == checks.UNVERIFIED
    (tmp_path / "run.json").write_text(json.dumps({"bench_report": 1, "profile": {"name": "seed-sim"},
                                                   "invocations": []}))
    scaling = {t: met for t, met, _ in checks.report_checks(tmp_path) if "data-scaling" in t}
    assert list(scaling.values()) == [False]
    (tmp_path / "data-scaling").mkdir()
    for f in ("README.md", "data_scaling.png"):
        (tmp_path / "data-scaling" / f).write_text("x")
    for profile, verdict in (("seed-sim", checks.UNVERIFIED), ("default", False)):
        # the report records no dataset here, so the summary's size cannot be compared with its models'
        (tmp_path / "data-scaling" / "data_scaling.json").write_text(json.dumps({"profile": profile,
                                                                                  "full_train_instances": 640}))
        assert [met for t, met, _ in checks.report_checks(tmp_path) if "data-scaling" in t] == [verdict]
