"""What the bench refuses before any output exists: a robot, parameter set or
rows it cannot score, in one line and with no report folder; an import's warning reaches the report; a
model another bench is training is waited for; a bench that ran no row does not exit 0."""
from __future__ import annotations

import json

import pytest

from hybrid_dyn.errors import HybridDynError

from helpers.timelimit import time_limit


@pytest.mark.parametrize("extra, message", [
    # finding 5: --robot ur5 on a 7-joint log wrote the report, then every analytic row failed
    (["--robot", "ur5"], "robot 'ur5' has 6 joints but dataset"),
    # finding 7: --params nonexist was refused only after --out was created
    (["--params", "nonexist"], "no parameter set 'nonexist'"),
    (["--params", "nonexist.json"], "parameter file not found"),
    # finding 7: --rows base-wrench on a log without a base wrench: '0/0 rows ok', exit 0
    (["--rows", "base-wrench"], "none of the selected rows applies to the data (base-wrench on my-panda: needs"),
])
def test_the_bench_refuses_what_it_cannot_score_before_the_report_folder_exists(panda_log, tmp_path, capsys, extra,
                                                                                 message):
    from hybrid_dyn.cli import main as cli_main

    args = ["bench", "--data", str(panda_log), "--out", str(tmp_path / "report"),
            "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]
    if "--rows" not in extra:
        args += ["--rows", "rnea"]
    capsys.readouterr()
    with time_limit(60, "bench"):
        assert cli_main(args + extra) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []  # no report folder, no lock file, no caches


def test_a_bad_parameter_file_is_refused_by_a_named_profile_before_any_data(tmp_path):
    from hybrid_dyn.bench.profiles import PROFILES

    f = tmp_path / "p.json"
    f.write_text(json.dumps({"links": [{"name": "panda_link1", "mass": 2.0, "com": [0, 0, 0],
                                        "inertia": [-0.01, 0, 0, 0.01, 0, 0.01]}]}))
    import dataclasses

    with pytest.raises(HybridDynError, match="not positive semi-definite"):
        dataclasses.replace(PROFILES.lookup("quick"), params=str(f))


@pytest.mark.slow  # imports a log and runs the bench's rnea row
def test_an_import_warning_reaches_the_bench_report(tmp_path, capsys):
    """Finding 7: the import's warning that the time column fits 'ms' never reached the bench report,
    which then showed RNEA at 0.552 Nm against 4e-6 with the right unit."""
    from hybrid_dyn.cli import main as cli_main
    from helpers.logs import write_log

    spec = write_log(tmp_path / "logs", n=200)
    log = tmp_path / "logs" / "log.csv"
    lines = log.read_text().splitlines()
    lines[1:] = [",".join([repr(float(row.split(",")[0]) * 1000)] + row.split(",")[1:]) for row in lines[1:]]
    log.write_text("\n".join(lines) + "\n")  # time in ms, the spec says s
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 0
    warning = "the time column fits the unit 'ms', not the declared 's'"
    assert warning in capsys.readouterr().out
    out = tmp_path / "report"
    cli_main(["bench", "--data", str(tmp_path / "ds"), "--out", str(out), "--rows", "rnea",
              "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")])
    assert warning in capsys.readouterr().out
    readme = (out / "README.md").read_text()
    assert "**import warning**" in readme and warning in readme
    assert warning in json.loads((out / "run.json").read_text())["datasets"]["my-panda"]["import_warnings"][0]


@pytest.mark.slow  # trains a tiny net
def test_a_bench_waits_for_a_model_another_bench_is_training_in_a_shared_runs_folder(panda_log, tmp_path):
    """Finding 7: two benches with different --out sharing runs/: the second one's row failed on the
    model lock. Here another run holds that model's lock for 3 s; the bench waits, then trains it."""
    import threading
    import time

    from hybrid_dyn.bench.runner import run_bench, work_dir
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.outputs import output_lock
    from helpers.bench import tiny_profile

    profile = tiny_profile([panda_log])
    profile = type(profile)(**{**profile.__dict__, "rows": ("seed-tau-mlp",)})
    model_dir = work_dir(profile, "my-panda", load_dataset(panda_log), tmp_path / "runs") / "models" / "seed-tau-mlp"
    held, release = threading.Event(), threading.Event()

    def other_run():
        with output_lock(model_dir, "model folder"):
            held.set()
            release.wait(3.0)

    other = threading.Thread(target=other_run)
    other.start()
    held.wait(10)
    t0 = time.perf_counter()
    try:
        with time_limit(120, "bench"):
            rows = run_bench(profile, tmp_path / "report", data_root=tmp_path / "data", work_root=tmp_path / "runs",
                             log=lambda m: None)
    finally:
        release.set()
        other.join()
    assert [(r["model"], r["status"]) for r in rows] == [("seed-tau-mlp", "ok")], rows
    assert time.perf_counter() - t0 >= 2.5  # it waited for the other run's lock
    assert (model_dir / "config.json").is_file()


def test_a_bench_that_ran_no_row_does_not_exit_0(tmp_path, capsys, monkeypatch):
    """Finding 7's '0/0 rows ok, exit 0', for a named profile: every real log missing, so every scenario
    is skipped with its reason; no row ran, which is no result (exit 1), and the report says why."""
    from hybrid_dyn.cli import main as cli_main

    monkeypatch.setenv("HYBRID_DYN_REAL_LOGS", str(tmp_path / "no-logs"))
    out = tmp_path / "report"
    with time_limit(120, "bench"):
        code = cli_main(["bench", "--profile", "real", "--out", str(out), "--data-root", str(tmp_path / "data"),
                         "--work-root", str(tmp_path / "runs")])
    assert "0/0 rows ok" in capsys.readouterr().out and code == 1
    assert "## Rows not run" in (out / "README.md").read_text()
