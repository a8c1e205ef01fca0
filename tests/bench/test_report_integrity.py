"""``hybrid-dyn report DIR`` redraws a bench report from its files alone, byte for byte, and refuses
what the bench did not write (whose folder, whose numbers): a results row
its predictions or digest contradict, another report's run.json, a hand-edited run.json, a user's
folder. Every refusal is one line naming the row or field, and writes nothing.
"""
from __future__ import annotations

import csv
import json
import shutil

import pytest

from hybrid_dyn.cli import main as cli_main

from helpers.bench import edit_results, killed_bench, tiny_profile
from helpers.messages import says


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


def _copy_report(tmp, name):
    report = tmp / name
    shutil.copytree(tmp / "report", report)
    return report


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
    edit_results(report, "identified-ols", **cells)
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
    assert says(err, "results.csv", "my-panda / joint_torque / rnea", "differs"), err
    edit_results(report, "rnea", **next(r for r in csv.DictReader((tmp / "other-report" / "results.csv").open())))
    assert cli_main(["report", str(report)]) == 2
    err = capsys.readouterr().err
    assert says(err, "my-panda / joint_torque / identified-ols", "run.json"), err  # the next row, in scoring order
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
def test_report_refuses_an_edited_run_json_field(bench, capsys):
    """Finding 6: wall_seconds null was a traceback; now any edit of a run.json field the README quotes
    (its digest is recorded beside results.csv's) is one error, and nothing is redrawn."""
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
    for key in ("report_files", "requested"):  # the records report deletes and reports by: digested too
        (report / "run.json").write_text(json.dumps({**meta, key: [*meta[key], "README.md"]}))
        assert cli_main(["report", str(report)]) == 2
        assert "run.json differs from what the bench wrote" in capsys.readouterr().err


@pytest.mark.slow  # the shared fixture: a tiny bench, ~25 s on 2 busy cores
def test_report_removes_only_the_figures_it_recorded(bench, capsys):
    """Stale figures were removed by file-name prefix, and with them a user's
    traces_my_experiment.png and rmse_by_family_mine_v2.png. The bench records in run.json the files the
    report wrote; a figure recorded and no longer drawn (stale traces of another dataset; here:
    its predictions are gone) is removed, and nothing else."""
    tmp, _, _ = bench
    report = _copy_report(tmp, "stale-figures")
    users = {"traces_my_experiment.png": b"mine", "rmse_by_family_mine_v2.png": b"mine too",
             "learning_curves_old.png": b"mine", "my-plot.png": b"mine"}
    for name, data in users.items():
        (report / name).write_bytes(data)
    assert cli_main(["report", str(report)]) == 0
    assert sorted(n for n in users if not (report / n).is_file()) == []
    assert all((report / name).read_bytes() == data for name, data in users.items())
    recorded = json.loads((report / "run.json").read_text())["report_files"]
    assert {"README.md", "joint_torque.md", "traces_joint_torque_my-panda.png"} <= set(recorded), recorded
    (report / "predictions.h5").unlink()  # the traces are no longer drawn: the recorded one is stale
    assert cli_main(["report", str(report)]) == 0
    assert not (report / "traces_joint_torque_my-panda.png").exists()
    assert (report / "rmse_by_family_joint_torque.png").is_file()
    assert all((report / name).read_bytes() == data for name, data in users.items())
    now = json.loads((report / "run.json").read_text())["report_files"]
    assert set(recorded) - set(now) == {"traces_joint_torque_my-panda.png"} and not set(users) & set(now)
    assert cli_main(["report", str(report)]) == 0  # run.json, re-recorded, still checks


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
    edit_results(tmp / "stopped", "rnea", rmse="1.0")
    capsys.readouterr()
    assert cli_main(["report", str(tmp / "stopped")]) == 2
    assert "row my-panda / joint_torque / rnea" in capsys.readouterr().err


@pytest.mark.slow  # a bench in a child process, killed after its first row: ~20 s on 2 busy cores
def test_the_report_of_a_bench_killed_with_kill_9_says_so_at_the_top(bench, capsys):
    """After kill -9 the README headlined the rows that ran with no word that the run
    was interrupted or which rows never ran, and said the machine was "not recorded in run.json (a report
    written before it was)", which was not why."""
    tmp, _, _ = bench
    out = tmp / "killed"
    rows = ("rnea", "torques-pinv", "identified-ols", "seed-tau-mlp")
    assert killed_bench(tmp / "my-log", out, rows, "joint_torque rnea ", tmp / "data", tmp / "runs") == -9
    assert [r["model"] for r in csv.DictReader((out / "results.csv").open())] == ["rnea"]
    capsys.readouterr()
    assert cli_main(["report", str(out)]) == 0
    readme = (out / "README.md").read_text()
    top = readme.split("## What was run")[0]
    notice = next((line for line in top.splitlines() if "did not finish" in line), None)
    assert notice is not None, top
    assert says(notice, "2 of the 4 rows requested never ran", "`my-panda / joint_torque / identified-ols`",
                "`my-panda / joint_torque / seed-tau-mlp`"), top
    # rnea ran; torques-pinv does not apply to the log (needs what it lacks): listed with its reason instead
    assert "joint_torque / rnea`" not in notice and "torques-pinv" not in notice
    assert "- my-panda: `torques-pinv` (tip force): needs" in readme
    assert "machine: not recorded in run.json (the bench records it when an invocation finishes, and this one " \
           "did not)" in readme and "a report written before it was" not in readme
    # Finished by a rerun: the notice goes, the machine is recorded.
    from hybrid_dyn.bench.runner import run_bench

    one = tiny_profile([tmp / "my-log"])
    run_bench(type(one)(**{**one.__dict__, "rows": rows}), out, data_root=tmp / "data", work_root=tmp / "runs",
              log=lambda m: None)
    readme = (out / "README.md").read_text()
    assert "did not finish" not in readme and "- machine: not recorded" not in readme


@pytest.mark.slow  # a bench in a child process, killed once it has claimed the folder: ~15 s
def test_a_bench_taking_over_another_profiles_folder_clears_its_outputs_first(bench, capsys):
    """A killed bench that was taking over another profile's folder left that profile's
    README and tables beside its own run.json. Now its outputs go in the step that writes the new run.json;
    what the old report did not record (a user's file) stays."""
    tmp, _, _ = bench
    out = _copy_report(tmp, "taken-over")
    old = json.loads((out / "run.json").read_text())
    users = {"traces_my_experiment.png": b"mine", "notes.txt": b"mine too"}
    for name, data in users.items():
        (out / name).write_bytes(data)
    # Another profile (one row), killed as soon as it starts on its scenario: after it claimed the folder.
    assert killed_bench(tmp / "my-log", out, ("rnea",), "[bench] scenario", tmp / "data", tmp / "runs") == -9
    meta = json.loads((out / "run.json").read_text())
    assert meta["profile"]["rows"] == ["rnea"]
    left = [n for n in ["README.md", "joint_torque.md", "joint_torque.tex", "traces_joint_torque_my-panda.png",
                        "predictions.h5", *old.get("report_files", [])] if (out / n).exists()]
    assert not left, left
    assert meta["invocations"][-1]["finished"] is None
    assert list(csv.DictReader((out / "results.csv").open())) == []
    assert all((out / name).read_bytes() == data for name, data in users.items())
    capsys.readouterr()
    assert cli_main(["report", str(out)]) == 0  # a report of no row yet, saying what never ran
    top = (out / "README.md").read_text().split("## What was run")[0]
    assert any(says(line, "did not finish", "1 of the 1 rows requested never ran", "`my-panda / joint_torque / rnea`")
               for line in top.splitlines()), top
    assert all((out / name).read_bytes() == data for name, data in users.items())
