"""The bench on any dataset: ``hybrid-dyn bench --data DIR`` on a tiny log
imported in the test, the rows that apply run and the rest are skipped with their reason; the report is
redrawn from its files (``hybrid-dyn report DIR``) byte for byte; a bad ``--robot`` fails before any work.

References: the rnea row's stored predictions against Pinocchio's RNEA called here on the same samples,
and the stored targets against the imported dataset itself.
"""
from __future__ import annotations

import csv
import json

import h5py
import numpy as np
import pytest

from hybrid_dyn.analytic.robot import load_robot
from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.data import load_dataset

from helpers.bench import tiny_profile
from helpers.messages import says
from helpers.logs import write_log

TINY_TRAIN = ["--workers", "1"]


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
def test_bench_on_an_imported_log_runs_what_applies_and_says_why_the_rest_does_not(bench):
    tmp, rows, messages = bench
    ran = {r["model"]: r for r in rows}
    assert set(ran) == {"rnea", "seed-tau-mlp", "identified-ols"}
    # The log's torques are white noise (helpers.logs.write_log): no Panda's bodies fit them, and the identified
    # row says so (implausible, scored and named, never headlined); the others are ok.
    assert {r["model"]: r["status"] for r in rows} == {"rnea": "ok", "seed-tau-mlp": "ok",
                                                       "identified-ols": "implausible"}, \
        [(r["model"], r.get("error")) for r in rows]
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
        # in scoring order: the rows that train nothing while the learned ones train, then the learned ones
        assert json.loads(grp["joint_torque"].attrs["order"]) == ["rnea", "identified-ols", "seed-tau-mlp"]
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
def test_every_row_has_its_cpu_time_and_the_invocation_its_own(bench):
    """results.csv carries each row's training and scoring CPU seconds, run.json each invocation's.
    A trained row's figure is the one its model file recorded (not the CPU of loading it again); a row fitted
    in the bench's process (identified-ols: the identification in its build) has that fit's."""
    from hybrid_dyn.learn import load_model
    from hybrid_dyn.learn.trained_model import recorded_train_cpu

    tmp, _, _ = bench
    with open(tmp / "report" / "results.csv", newline="") as f:
        rows = {r["model"]: r for r in csv.DictReader(f)}
    for r in rows.values():
        assert float(r["train_cpu_seconds"]) >= 0 and float(r["score_cpu_seconds"]) > 0, r["model"]
    assert float(rows["identified-ols"]["train_cpu_seconds"]) > 0
    net = load_model(next((tmp / "runs").rglob("models/seed-tau-mlp")))
    assert recorded_train_cpu(net) > 0
    assert float(rows["seed-tau-mlp"]["train_cpu_seconds"]) == pytest.approx(recorded_train_cpu(net), rel=1e-5)
    (inv,) = json.loads((tmp / "report" / "run.json").read_text())["invocations"]
    # This process scored every row (and trained seed-tau-mlp: one worker is this process).
    assert inv["cpu_seconds"] >= sum(float(r["score_cpu_seconds"]) + float(r["train_cpu_seconds"])
                                     for r in rows.values())


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
    reasons = {k["model"]: k["reason"] for k in skipped}
    assert set(reasons) == {"rnea", "identified-ols"}  # the rows that need a URDF, each saying why
    assert all(says(r, "URDF", "'unknown'", "data only") for r in reasons.values()), reasons


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


@pytest.mark.slow  # imports a log and runs the bench twice
def test_an_interrupted_invocation_keeps_its_wall_time_and_the_report_adds_the_parts(tmp_path):
    """A bench killed halfway (Ctrl-C, the OOM killer) leaves its time so far in run.json; the rerun that
    finishes it keeps that part, and the README prints every part and their sum."""
    from hybrid_dyn.bench.runner import run_bench

    spec = write_log(tmp_path / "logs", n=200)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "log")]) == 0
    profile = type(tiny_profile([tmp_path / "log"]))(**{**tiny_profile([tmp_path / "log"]).__dict__,
                                                        "rows": ("rnea", "seed-tau-mlp")})
    roots = dict(data_root=tmp_path / "data", work_root=tmp_path / "runs")

    def killed_after_first_row(message):
        if "rmse=" in message:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_bench(profile, tmp_path / "r", log=killed_after_first_row, **roots)
    (part,) = json.loads((tmp_path / "r" / "run.json").read_text())["invocations"]
    assert part["finished"] is None and part["rows"] == 1 and part["wall_seconds"] > 0
    assert cli_main(["report", str(tmp_path / "r")]) == 0  # the interrupted bench's row stays checkable

    run_bench(profile, tmp_path / "r", log=lambda m: None, **roots)
    meta = json.loads((tmp_path / "r" / "run.json").read_text())
    first, second = meta["invocations"]
    assert first == part and second["finished"] is not None and second["rows"] == 2
    assert first["cold_start"] and not second["cold_start"]  # the second found the first's trained net
    readme = (tmp_path / "r" / "README.md").read_text()
    total = (first["wall_seconds"] + second["wall_seconds"]) / 60
    assert f"all invocations [min]: {first['wall_seconds'] / 60:.1f} (not finished), " in readme
    assert f"in all {total:.1f} min" in readme


@pytest.mark.slow  # imports a log and runs the bench three times
def test_a_resume_never_vouches_for_rows_it_did_not_compute_and_a_takeover_clears_the_other_profiles(tmp_path):
    """A results.csv edited by hand stays refused by ``hybrid-dyn report`` after a resume is interrupted
    before its first row; a folder taken over by another profile keeps none of that profile's rows, and an
    interrupt while training keeps its time (the heartbeat's last record)."""
    from hybrid_dyn.bench import runner
    from hybrid_dyn.bench.results import read_results, write_results

    spec = write_log(tmp_path / "logs", n=200)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "log")]) == 0
    # rnea-bw does not apply (the log has no base wrench): its "skipping" line comes after the dataset is
    # recorded and before predictions.h5 is touched, the moment the resume is interrupted below.
    one = type(tiny_profile([tmp_path / "log"]))(**{**tiny_profile([tmp_path / "log"]).__dict__,
                                                    "rows": ("rnea", "rnea-bw", "identified-ols")})
    roots = dict(data_root=tmp_path / "data", work_root=tmp_path / "runs")
    out = tmp_path / "r"
    runner.run_bench(one, out, log=lambda m: None, **roots)
    rows = read_results(out / "results.csv")
    rows[1]["val_loss"] = "1e-09"  # a hand edit
    write_results(out / "results.csv", rows)
    assert cli_main(["report", str(out)]) == 2

    def killed_at(words):
        def log(message):
            if words in message:
                raise KeyboardInterrupt
        return log

    with pytest.raises(KeyboardInterrupt):  # after the dataset was found and recorded, before any row
        runner.run_bench(one, out, log=killed_at("skipping rnea-bw"), **roots)
    assert json.loads((out / "run.json").read_text())["invocations"][-1]["finished"] is None
    assert cli_main(["report", str(out)]) == 2  # the edit is still caught

    runner.run_bench(one, out, log=lambda m: None, **roots)  # the way back from an edit: rerun the bench
    assert cli_main(["report", str(out)]) == 0
    with pytest.raises(KeyboardInterrupt):  # after predictions.h5 got this invocation's test data, before any row
        runner.run_bench(one, out, log=killed_at("training"), **roots)
    assert cli_main(["report", str(out)]) == 0  # the earlier rows keep their predictions beside results.csv

    other = type(one)(**{**one.__dict__, "rows": ("rnea",), "seed": 7})
    with pytest.raises(KeyboardInterrupt):
        runner.run_bench(other, out, log=killed_at("training"), **roots)
    assert read_results(out / "results.csv") == []  # the first profile's rows are gone, not relabelled


def test_the_heartbeat_records_the_time_of_a_long_step_while_it_runs(tmp_path):
    """Generation and training write nothing for hours: the clock records every ``period`` seconds, so a
    bench killed by a signal no handler sees (the OOM killer) loses at most one period."""
    import time

    from hybrid_dyn.bench.run_record import InvocationClock

    (tmp_path / "run.json").write_text(json.dumps({"bench_report": 1, "invocations": [], "profile": {"name": "t"}}))
    clock = InvocationClock([], period=0.05)
    with clock.heartbeat(tmp_path, []):
        time.sleep(0.5)
        (during,) = json.loads((tmp_path / "run.json").read_text())["invocations"]
    assert during["finished"] is None and 0.2 < during["wall_seconds"] <= clock.seconds()
    assert "results_digest" not in json.loads((tmp_path / "run.json").read_text())  # vouches for nothing
