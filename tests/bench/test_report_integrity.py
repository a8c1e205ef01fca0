"""``hybrid-dyn report DIR`` redraws a bench report from its files alone, byte for byte, and refuses
what the bench did not write (issue 15, item 6; issue 28: whose folder, whose numbers): a results row
its predictions or digest contradict, another report's run.json, a hand-edited run.json, a user's
folder. Every refusal is one line naming the row or field, and writes nothing.
"""
from __future__ import annotations

import csv
import json
import shutil

import pytest

from hybrid_dyn.cli import main as cli_main

from helpers.bench import tiny_profile
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
    assert says(err, "results.csv", "my-panda / joint_torque / rnea", "differs"), err
    _edit_row(report, "rnea", **next(r for r in csv.DictReader((tmp / "other-report" / "results.csv").open())))
    assert cli_main(["report", str(report)]) == 2
    err = capsys.readouterr().err
    assert says(err, "my-panda / joint_torque / seed-tau-mlp", "run.json"), err
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
