"""The bench on any dataset (issue 15, items 1 and 6): ``hybrid-dyn bench --data DIR`` on a tiny log
imported in the test, the rows that apply run and the rest are skipped with their reason; the report is
redrawn from its files (``hybrid-dyn report DIR``) byte for byte; a bad ``--robot`` fails before any work.

References: the rnea row's stored predictions against Pinocchio's RNEA called here on the same samples,
and the stored targets against the imported dataset itself.
"""
from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from hybrid_dyn.analytic.robot import load_robot
from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.data import load_dataset

NV = 7
HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
# A few rows of each kind, to keep the test seconds: analytic (one runs, one needs a base sensor), a tip-force
# net (no tip force in a log), a seed net (trains one tiny epoch) and a row identified on the log itself.
ROWS = ["rnea", "rnea-bw", "torques-pinv", "seed-tip-1", "seed-tau-mlp", "identified-ols"]
TINY_TRAIN = ["--workers", "1"]


def write_log(folder: Path, n: int = 400, hz: float = 100.0) -> Path:
    """A 4 s log of slow sines about the Panda's home pose and torques that are any numbers, as a CSV."""
    t = np.arange(n) / hz
    w = np.linspace(1.0, 2.5, NV)
    q = HOME + 0.3 * np.sin(w * t[:, None])
    qd = 0.3 * w * np.cos(w * t[:, None])
    tau = np.random.default_rng(0).normal(0, 5, (n, NV))
    header = ",".join(["t"] + [f"{k}{j}" for k in ("q", "qd", "tau") for j in range(1, NV + 1)])
    folder.mkdir(parents=True, exist_ok=True)
    np.savetxt(folder / "log.csv", np.column_stack([t, q, qd, tau]), delimiter=",", header=header, comments="",
               fmt="%.17g")
    cols = lambda k: "[" + ", ".join(f'"{k}{j}"' for j in range(1, NV + 1)) + "]"  # noqa: E731
    spec = folder / "spec.toml"
    spec.write_text(f'name = "my-panda"\nrobot = "panda"\ntool = "none"\n[source]\nfiles = ["log.csv"]\n'
                    f'[time]\ncolumn = "t"\n[columns]\nq = {cols("q")}\nqd = {cols("qd")}\ntau_m = {cols("tau")}\n'
                    '[trajectories]\nfrom = "blocks"\nn_blocks = 10\n[split]\nseed = 0\n')
    return spec


def tiny_profile(data, **kw):
    from hybrid_dyn.bench.profiles import profile_for_data

    return profile_for_data(data, families=(), rows=tuple(ROWS), workers=1,
                            train=dict(budget_steps=2, budget_evals=1, batch_size=64, progress=False), **kw)


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """A tiny imported log, and the bench on it (Python API: run_bench(profile_for_data(...)))."""
    from hybrid_dyn.bench.runner import run_bench

    tmp = tmp_path_factory.mktemp("bench-data")
    spec = write_log(tmp / "logs")
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp / "my-log")]) == 0
    messages = []
    rows = run_bench(tiny_profile([tmp / "my-log"]), tmp / "report", data_root=tmp / "data",
                     work_root=tmp / "runs", log=messages.append)
    return tmp, rows, messages


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
def test_bench_on_an_imported_log_runs_what_applies_and_says_why_the_rest_does_not(bench):
    tmp, rows, messages = bench
    ran = {r["model"]: r for r in rows}
    assert set(ran) == {"rnea", "seed-tau-mlp", "identified-ols"}
    assert all(r["status"] == "ok" for r in rows), [(r["model"], r.get("error")) for r in rows]
    assert {r["scenario"] for r in rows} == {"my-panda"}  # the manifest's scenario labels the tables
    meta = json.loads((tmp / "report" / "run.json").read_text())
    skipped = {k["model"]: k["reason"] for k in meta["skipped"]}
    assert skipped == {"rnea-bw": "needs base_wrench", "torques-pinv": "needs tau_J, tip_force",
                       "seed-tip-1": "needs base_wrench, tip_force"}
    for model, reason in skipped.items():  # printed, and written in the report
        assert any(model in m and reason in m for m in messages), model
    readme = (tmp / "report" / "README.md").read_text()
    assert "## Rows not run" in readme and "`rnea-bw` (joint torque): needs base_wrench" in readme
    assert "hybrid-dyn bench --data " in readme and "panda[tool=none]" in readme  # the variant the log names
    assert "Floors" not in readme and "NOT met" not in readme  # the project's floors are checks/acceptance.py
    assert meta["datasets"]["my-panda"]["robot"] == "panda[tool=none]"


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
def test_predictions_h5_holds_each_rows_test_predictions_and_their_targets(bench):
    tmp, rows, _ = bench
    ds = load_dataset(tmp / "my-log")
    robot = load_robot("panda[tool=none]")  # an independent call of the analytic model
    test = ds.split("test")
    with h5py.File(tmp / "report" / "predictions.h5", "r") as f:
        grp = f["my-panda"]
        assert json.loads(grp["joint_torque"].attrs["order"]) == ["rnea", "seed-tau-mlp", "identified-ols"]
        for inst in test:
            np.testing.assert_array_equal(grp["test"][inst.name]["tau_m"][()], inst["tau_m"])
            np.testing.assert_array_equal(grp["test"][inst.name]["t"][()], inst.t)
            pred = grp["joint_torque"]["rnea"][inst.name][()]
            assert pred.dtype == np.float64
            np.testing.assert_allclose(pred, robot.inverse_dynamics(inst.q, inst.qd, inst.qdd), rtol=0, atol=1e-9)
        # The stored predictions give results.csv's RMSE (to its 6 printed digits).
        tau = np.concatenate([inst["tau_m"] for inst in test])
        pred = np.concatenate([grp["joint_torque"]["identified-ols"][i.name][()] for i in test])
        rmse = float(next(r["rmse"] for r in rows if r["model"] == "identified-ols"))
        assert np.sqrt(np.mean((pred - tau) ** 2)) == pytest.approx(rmse, rel=1e-5)


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
def test_report_rebuilds_results_and_tables_byte_for_byte(bench, capsys):
    tmp, _, _ = bench
    report = tmp / "report-copy"
    shutil.copytree(tmp / "report", report)
    kept = {name: (report / name).read_bytes() for name in
            ("results.csv", "tip_force.md", "joint_torque.md", "tip_force.tex", "joint_torque.tex")}
    for name in [*kept, "README.md", "traces_joint_torque_my-panda.png", "rmse_by_family_joint_torque.png"]:
        (report / name).unlink()
    (report / "results.csv").write_bytes(kept["results.csv"])  # what report reads; it writes it again
    # No dataset, no model cache: the report is drawn from the folder's files alone.
    shutil.move(tmp / "my-log", tmp / "moved-log")
    shutil.move(tmp / "runs", tmp / "moved-runs")
    try:
        assert cli_main(["report", str(report)]) == 0
    finally:
        shutil.move(tmp / "moved-log", tmp / "my-log")
        shutil.move(tmp / "moved-runs", tmp / "runs")
    for name, data in kept.items():
        assert (report / name).read_bytes() == data, name
    for name in ("README.md", "traces_joint_torque_my-panda.png", "rmse_by_family_joint_torque.png"):
        assert (report / name).is_file(), name
    assert (report / "README.md").read_text() == (tmp / "report" / "README.md").read_text()

    # A report from before predictions.h5: the tables still, the figures that need predictions skipped, said so.
    (report / "predictions.h5").unlink()
    (report / "traces_joint_torque_my-panda.png").unlink()
    capsys.readouterr()
    assert cli_main(["report", str(report)]) == 0
    out = capsys.readouterr().out
    assert "figures not drawn" in out and "predictions.h5" in out
    assert not (report / "traces_joint_torque_my-panda.png").exists()
    for name, data in kept.items():
        assert (report / name).read_bytes() == data, name


def test_report_refuses_a_folder_that_is_not_a_bench_report(tmp_path, capsys):
    (tmp_path / "results.csv").write_text("mine\n")
    assert cli_main(["report", str(tmp_path)]) == 2
    assert "not a bench report folder" in capsys.readouterr().err
    assert (tmp_path / "results.csv").read_text() == "mine\n"


def test_a_bad_robot_name_fails_before_any_work_with_the_accepted_names(tmp_path, capsys):
    spec = write_log(tmp_path / "logs", n=200)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "log")]) == 0
    capsys.readouterr()
    out = tmp_path / "report"
    assert cli_main(["bench", "--data", str(tmp_path / "log"), "--out", str(out), "--robot", "pandaa",
                     "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs"), *TINY_TRAIN]) == 2
    err = capsys.readouterr().err
    assert "unknown robot 'pandaa'" in err and "panda" in err.replace("'pandaa'", "") and "ur5" in err
    assert "tool=none" in err  # the variants a name may carry
    assert not out.exists() and not (tmp_path / "runs").exists() and not (tmp_path / "data").exists()
    # The same from Python, before any dataset is read.
    from hybrid_dyn.errors import HybridDynError

    with pytest.raises(HybridDynError, match="unknown robot 'pandaa'"):
        tiny_profile([tmp_path / "does-not-exist"], robot="pandaa")


def test_a_robot_known_for_data_only_runs_the_black_box_rows_and_skips_the_urdf_rows(tmp_path):
    from hybrid_dyn.bench.runner import run_bench

    spec = write_log(tmp_path / "logs", n=200)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "log")]) == 0
    profile = tiny_profile([tmp_path / "log"], robot="unknown")
    profile = type(profile)(**{**profile.__dict__, "rows": ("rnea", "identified-ols", "seed-tau-mlp")})
    rows = run_bench(profile, tmp_path / "report", data_root=tmp_path / "data", work_root=tmp_path / "runs",
                     log=lambda m: None)
    # The black-box net trains and scores (it needs no robot model: nothing of its input is tared).
    assert [(r["model"], r["status"]) for r in rows] == [("seed-tau-mlp", "ok")], rows
    skipped = json.loads((tmp_path / "report" / "run.json").read_text())["skipped"]
    assert {k["model"]: k["reason"] for k in skipped} == {
        "rnea": "needs a URDF for robot 'unknown' (known for data only)",
        "identified-ols": "needs a URDF for robot 'unknown' (known for data only)"}


def test_acceptance_floors_are_a_benchmark_of_their_own(tmp_path, capsys):
    """checks/acceptance.py prints each floor with its numbers and met / NOT met; the report does not."""
    import importlib.util

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
    spec = importlib.util.spec_from_file_location("acceptance", Path(__file__).parents[1] / "checks" / "acceptance.py")
    acceptance = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(acceptance)
    assert acceptance.main(["--report", str(tmp_path)]) == 1  # one floor is not met
    out = capsys.readouterr().out
    assert ("- NOT met: issue 7: joint torque, mismatch-ext: identified-consistent <= 0.5 x nominal RNEA (all samples) "
            "(identified-consistent 1.2000 Nm / rnea 2.0000 Nm = 0.600)") in out
    assert "- met: issue 7: joint torque, mismatch-ext: identified-consistent <= 0.5 x nominal RNEA (free motion" in out
    assert "- met: issue 15: real-panda: identified-consistent <= 0.4 x nominal RNEA" in out and "= 0.200)" in out
    assert ("- met: issue 15: real-panda: best residual on the identified model <= 1.0 x identified-consistent (aim 0.9) "
            "(residual-rnea-identified 0.2880 Nm / identified-consistent 0.3200 Nm = 0.900)") in out
    (tmp_path / "run.json").write_text(json.dumps({"bench_report": 1, "profile": {"name": "t"}}))
    write_report(tmp_path, read_results(tmp_path / "results.csv"), {"profile": {"name": "t"}, "wall_seconds": 1.0},
                 log=lambda m: None)
    readme = (tmp_path / "README.md").read_text()
    assert "## Floors" not in readme and "NOT met" not in readme and "- met:" not in readme
    assert "identified (identified-consistent) 1.200" in readme  # the findings stay


@pytest.mark.slow  # imports a log and runs the bench several times
def test_bench_rows_and_families_on_the_command_line_choose_what_runs(tmp_path, capsys):
    spec = write_log(tmp_path / "logs", n=200)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "log")]) == 0
    roots = ["--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]
    out = tmp_path / "report"
    assert cli_main(["bench", "--data", str(tmp_path / "log"), "--out", str(out), "--rows", "rnea, identified-ols",
                     *roots]) == 0
    assert {r["model"] for r in csv.DictReader((out / "results.csv").open())} == {"rnea", "identified-ols"}
    capsys.readouterr()
    for bad, named in ((["--rows", "rnea,rneaa"], "rneaa"), (["--families", "analytik"], "analytik"),
                       (["--rows", " , "], "name no row")):
        bad_out = tmp_path / f"bad-{named}"
        assert cli_main(["bench", "--data", str(tmp_path / "log"), "--out", str(bad_out), *bad, *roots]) == 2
        assert named in capsys.readouterr().err
        assert not bad_out.exists()


def test_a_missing_dataset_is_refused_before_the_report_folder_is_made(tmp_path, capsys):
    out = tmp_path / "report"
    assert cli_main(["bench", "--data", str(tmp_path / "no-such-log"), "--out", str(out),
                     "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]) == 2
    assert "no-such-log" in capsys.readouterr().err
    assert not out.exists()


def test_the_data_control_divides_each_learned_row_by_its_own_reports_physics(tmp_path, capsys):
    """hybrid-dyn compare: two reports on different test instances compare through their analytic rows."""
    from hybrid_dyn.bench.results import write_results

    def row(model, family, rmse, epochs=""):
        return {"task": "joint_torque", "scenario": "paper-noext", "model": model, "family": family, "status": "ok",
                "rmse": rmse, "val_loss": 0.1, "test_loss": 0.1, "nmse": 0.1, "epochs": epochs, "best_epoch": ""}

    for name, rnea, mlp in (("small", 0.5, 5.0), ("large", 0.25, 1.0)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "run.json").write_text(json.dumps({"profile": {"scenario_overrides": {
            "paper-noext": {"n_instances": 10 if name == "small" else 40, "trajectories": [5, 10]}}}}))
        write_results(tmp_path / name / "results.csv", [row("rnea", "analytic", rnea), row("rnea-bw", "analytic", 9.0),
                                                         row("seed-tau-mlp", "seed-net", mlp, 12)])
    assert cli_main(["compare", str(tmp_path / "small"), str(tmp_path / "large")]) == 0
    out = capsys.readouterr().out
    assert "small `rnea` 0.500 Nm, large `rnea` 0.250 Nm" in out  # the best analytic row of each report
    assert "| seed-tau-mlp | seed-net | 5.000 | 10.00 | 12 (-) | 1.000 | 4.00 | 12 (-) | 0.40x |" in out
    assert "10 x (5, 10)" in out and "40 x (5, 10)" in out


@pytest.mark.slow  # imports a log and runs the bench several times
def test_a_rerun_keeps_its_profiles_wall_times_and_drops_another_profiles(tmp_path):
    """A cached rerun must not hide the first run's wall time; a report of another profile is other work."""
    from hybrid_dyn.bench.runner import run_bench

    spec = write_log(tmp_path / "logs", n=200)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "log")]) == 0
    roots = dict(data_root=tmp_path / "data", work_root=tmp_path / "runs", log=lambda m: None)
    one = type(tiny_profile([tmp_path / "log"]))(**{**tiny_profile([tmp_path / "log"]).__dict__, "rows": ("rnea",)})
    other = type(one)(**{**one.__dict__, "rows": ("rnea", "identified-ols")})
    wall = lambda: [i["wall_seconds"] for i in json.loads((tmp_path / "r" / "run.json").read_text())["invocations"]]  # noqa: E731
    run_bench(one, tmp_path / "r", **roots)
    run_bench(one, tmp_path / "r", **roots)
    first = wall()
    assert len(first) == 2
    run_bench(other, tmp_path / "r", **roots)
    assert len(wall()) == 1 and wall()[0] not in first


# ------------------------------------------------------------------ issue 28: whose folder, whose numbers
def _copy_report(tmp, name):
    report = tmp / name
    shutil.copytree(tmp / "report", report)
    return report


def _edit_row(report, which, **cells):
    rows = list(csv.DictReader((report / "results.csv").open()))
    for r in rows:
        if r["model"] == which:
            r.update(cells)
    with open(report / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
@pytest.mark.parametrize("cells, column", [
    ({"rmse": "9.99"}, "rmse = '9.99', its stored predictions give"),  # finding 3: printed as 9.9900
    ({"rmse_3": "0.001"}, "rmse_3 = '0.001'"),
    ({"rmse": "abc"}, "rmse = 'abc'"),  # finding 6: a non-numeric rmse was a traceback
    ({"rmse": ""}, "rmse = ''"),
    ({"val_loss": "0.5"}, "differs from what the bench wrote"),  # not in predictions.h5: the digest names it
])
def test_report_refuses_a_results_row_that_is_not_what_the_bench_computed(bench, capsys, cells, column):
    tmp, _, _ = bench
    report = _copy_report(tmp, f"edited-{'-'.join(cells)}-{len(cells[next(iter(cells))])}")
    before = {p.name: p.read_bytes() for p in report.iterdir() if p.is_file()}
    _edit_row(report, "identified-ols", **cells)
    edited = (report / "results.csv").read_bytes()
    capsys.readouterr()
    assert cli_main(["report", str(report)]) == 2
    err = capsys.readouterr().err
    assert "row my-panda / joint_torque / identified-ols" in err and column in err, err
    assert len(err.strip().splitlines()) == 1
    # Nothing was written: the tables and README are the bench's, results.csv is the edited one.
    after = {p.name: p.read_bytes() for p in report.iterdir() if p.is_file()}
    assert after == {**before, "results.csv": edited}
    # Without predictions.h5 the digest alone still refuses the row.
    (report / "predictions.h5").unlink()
    assert cli_main(["report", str(report)]) == 2
    assert "row my-panda / joint_torque / identified-ols" in capsys.readouterr().err


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
def test_report_refuses_another_reports_run_json_and_a_run_json_without_digest(bench, capsys):
    """Finding 3: another report's run.json copied in named the wrong dataset above the right numbers."""
    from hybrid_dyn.bench.runner import run_bench

    tmp, _, _ = bench
    one = tiny_profile([tmp / "my-log"])
    other = type(one)(**{**one.__dict__, "rows": ("rnea",)})
    run_bench(other, tmp / "other-report", data_root=tmp / "data", work_root=tmp / "runs", log=lambda m: None)
    report = _copy_report(tmp, "swapped")
    shutil.copy(tmp / "other-report" / "run.json", report / "run.json")
    capsys.readouterr()
    assert cli_main(["report", str(report)]) == 2
    err = capsys.readouterr().err
    # The first row already differs (its timings are the other run's); a row the other run lacks is named too.
    assert "results.csv row my-panda / joint_torque / rnea differs from what the bench wrote" in err, err
    _edit_row(report, "rnea", **next(r for r in csv.DictReader((tmp / "other-report" / "results.csv").open())))
    assert cli_main(["report", str(report)]) == 2
    assert "row my-panda / joint_torque / seed-tau-mlp is not one the bench recorded in run.json" in \
        capsys.readouterr().err
    meta = json.loads((tmp / "report" / "run.json").read_text())
    del meta["results_digest"]
    (report / "run.json").write_text(json.dumps(meta))
    assert cli_main(["report", str(report)]) == 2
    assert "records no digest of results.csv" in capsys.readouterr().err


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
@pytest.mark.parametrize("edit, message", [
    ({"profile": "quick"}, "not a run.json of hybrid-dyn bench"),  # finding 6: a traceback before
    ({"wall_seconds": "soon"}, "wall_seconds must be a number of seconds or null"),
    ({"invocations": [{"wall_seconds": "x"}]}, "invocations must be"),
    ({"scenarios": 3}, "scenarios must be"),
    ({"machine": {"machine": "x"}}, "machine must be"),
])
def test_report_refuses_a_hand_edited_run_json_in_one_line(bench, capsys, edit, message):
    tmp, _, _ = bench
    report = _copy_report(tmp, f"meta-{next(iter(edit))}")
    meta = {**json.loads((report / "run.json").read_text()), **edit}
    (report / "run.json").write_text(json.dumps(meta))
    readme = (report / "README.md").read_bytes()
    capsys.readouterr()
    assert cli_main(["report", str(report)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert (report / "README.md").read_bytes() == readme


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
def test_report_refuses_an_edited_run_json_field_and_drops_stale_figures(bench, capsys):
    """Finding 6: wall_seconds null was a traceback; now any edit of a run.json field the README quotes
    (its digest is recorded beside results.csv's) is one error, and nothing is redrawn. Finding 7: a
    report folder reused for another dataset kept the old traces_*.png (a user's own png is left alone)."""
    tmp, _, _ = bench
    report = _copy_report(tmp, "null-wall")
    meta = json.loads((report / "run.json").read_text())
    for edit in ({"wall_seconds": None}, {"datasets": {"my-panda": {**meta["datasets"]["my-panda"], "path": "x"}}}):
        (report / "run.json").write_text(json.dumps({**meta, **edit}))
        readme = (report / "README.md").read_bytes()
        capsys.readouterr()
        assert cli_main(["report", str(report)]) == 2
        assert "run.json differs from what the bench wrote" in capsys.readouterr().err
        assert (report / "README.md").read_bytes() == readme
    (report / "run.json").write_text(json.dumps(meta))
    (report / "traces_joint_torque_old-log.png").write_bytes(b"\x89PNG old")
    (report / "my-plot.png").write_bytes(b"mine")
    assert cli_main(["report", str(report)]) == 0
    assert not (report / "traces_joint_torque_old-log.png").exists()
    assert (report / "traces_joint_torque_my-panda.png").is_file()
    assert (report / "my-plot.png").read_bytes() == b"mine"


@pytest.mark.slow  # needs the fixture's imported log
def test_bench_and_report_refuse_a_users_folder_with_a_run_json_of_their_own(bench, capsys):
    """Finding 2: any run.json with a 'profile' key counted as the bench's: both files were replaced, and
    report wrote its tables there before crashing."""
    tmp, _, _ = bench
    user = tmp / "my-experiment"
    user.mkdir()
    files = {"run.json": json.dumps({"profile": "my-experiment", "lr": 0.01}), "README.md": "# my notes\n",
             "results.csv": "epoch,loss\n1,0.5\n"}
    for name, text in files.items():
        (user / name).write_text(text)
    capsys.readouterr()
    assert cli_main(["bench", "--data", str(tmp / "my-log"), "--out", str(user), "--rows", "rnea",
                     "--data-root", str(tmp / "data"), "--work-root", str(tmp / "runs")]) == 2
    assert "refusing to replace" in capsys.readouterr().err
    assert cli_main(["report", str(user)]) == 2
    assert "not a run.json of hybrid-dyn bench" in capsys.readouterr().err
    assert {p.name: p.read_text() for p in user.iterdir()} == files


@pytest.mark.slow  # needs the fixture's imported log
def test_an_interrupted_benchs_rows_stay_checkable_by_report(bench, capsys):
    """run.json records the digest after every row, so the report of a bench stopped after its first row
    is redrawn (that row checked against its predictions), not refused as unverifiable."""
    from hybrid_dyn.bench.runner import run_bench

    tmp, _, _ = bench
    one = tiny_profile([tmp / "my-log"])
    profile = type(one)(**{**one.__dict__, "rows": ("rnea", "identified-ols")})

    def log(message):
        if "joint_torque rnea" in message and "rmse=" in message:
            raise KeyboardInterrupt  # as a Ctrl-C right after the first row's files are written

    with pytest.raises(KeyboardInterrupt):
        run_bench(profile, tmp / "stopped", data_root=tmp / "data", work_root=tmp / "runs", log=log)
    assert [r["model"] for r in csv.DictReader((tmp / "stopped" / "results.csv").open())] == ["rnea"]
    assert cli_main(["report", str(tmp / "stopped")]) == 0
    assert "| rnea |" in (tmp / "stopped" / "joint_torque.md").read_text()
    _edit_row(tmp / "stopped", "rnea", rmse="1.0")
    capsys.readouterr()
    assert cli_main(["report", str(tmp / "stopped")]) == 2
    assert "row my-panda / joint_torque / rnea" in capsys.readouterr().err
