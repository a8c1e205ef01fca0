"""hybrid_dyn.bench.compare (hybrid-dyn compare): two reports, each row against its own report's physics."""
import pytest

from hybrid_dyn.bench.compare import compare_reports
from hybrid_dyn.cli import main as cli_main

from helpers.bench import edit_results, written_report


def _report(folder, rows, overrides=None):
    return written_report(folder, [
        {"task": task, "scenario": "s", "model": model, "family": family, "status": "ok", "rmse": rmse,
         "val_loss": 0.1, "test_loss": 0.1, "nmse": 0.1, "epochs": "", "best_epoch": ""}
        for task, model, family, rmse in rows], profile={"scenario_overrides": overrides or {}})


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


# Compare reads a folder only as report does (the digests), and writes --out only where it may.
TWO = [("joint_torque", "rnea", "analytic", 0.25), ("joint_torque", "seed-tau-mlp", "seed-net", 1.568)]


def _compare(tmp_path, capsys, *extra):
    capsys.readouterr()
    rc = cli_main(["compare", str(tmp_path / "a"), str(tmp_path / "b"), *extra])
    out, err = capsys.readouterr()
    return rc, out, err.strip()


def test_compare_refuses_a_hand_edited_number_naming_the_row(tmp_path, capsys):
    """Finding 1: seed-tau-mlp's RMSE edited from 1.568 to 0.0123 in a copy of a report; report refused the
    folder, compare printed 0.012 and "0.01x" and exited 0."""
    _report(tmp_path / "a", TWO)
    _report(tmp_path / "b", TWO)
    assert _compare(tmp_path, capsys)[0] == 0
    edit_results(tmp_path / "b", "seed-tau-mlp", rmse="0.0123")
    rc, out, err = _compare(tmp_path, capsys)
    assert rc == 2 and out == "" and len(err.splitlines()) == 1, (out, err)
    assert "results.csv row s / joint_torque / seed-tau-mlp differs from what the bench wrote" in err, err
    assert cli_main(["report", str(tmp_path / "b")]) == 2  # the same folder, the same refusal
    assert capsys.readouterr().err.strip() == err


@pytest.mark.parametrize("run_json, results, message", [
    ('{"profile": "mine"}', None, "run.json: it is not a run.json of hybrid-dyn bench"),  # a user's run.json
    ('{"bench_report": 1, "profile": {"name"', None, "it is not a run.json of hybrid-dyn bench"),  # truncated
    ("[1, 2]", None, "it is not a run.json of hybrid-dyn bench"),
    (None, b"\xff\xfe\x00garbage\x81\n", "does not read as a results table"),
    (None, b"task,scenario,model\njoint_torque,s,rnea,extra\n", "line 2: its cells do not match the header"),
    (None, b"", "lacks rows the bench recorded"),
])
def test_compare_on_a_foreign_or_malformed_folder_is_one_error(tmp_path, capsys, run_json, results, message):
    """Finding 2: a user's run.json ({"profile": "mine"}) was AttributeError: 'str' object has no attribute
    'get'; any malformed run.json or results.csv is one line naming the file, and nothing is written."""
    _report(tmp_path / "a", TWO)
    _report(tmp_path / "b", TWO)
    if run_json is not None:
        (tmp_path / "b" / "run.json").write_text(run_json)
    if results is not None:
        (tmp_path / "b" / "results.csv").write_bytes(results)
    before = {p.name: p.read_bytes() for p in (tmp_path / "b").iterdir()}
    rc, out, err = _compare(tmp_path, capsys)
    assert rc == 2 and out == "" and err.startswith("error: ") and len(err.splitlines()) == 1, (out, err)
    assert message in err and str(tmp_path / "b") in err, err
    assert {p.name: p.read_bytes() for p in (tmp_path / "b").iterdir()} == before


def test_compare_out_refuses_a_users_file_and_replaces_only_its_own(tmp_path, capsys):
    """Finding 3: compare --out notes.md overwrote the user's notes.md."""
    _report(tmp_path / "a", TWO)
    _report(tmp_path / "b", TWO)
    notes = tmp_path / "notes.md"
    notes.write_text("# my notes\nweeks of them\n")
    rc, out, err = _compare(tmp_path, capsys, "--out", str(notes))
    assert rc == 2 and out == "" and err.startswith("error: refusing to replace") and str(notes) in err, err
    assert notes.read_text() == "# my notes\nweeks of them\n"
    mine = tmp_path / "mine.md"
    rc, out, _ = _compare(tmp_path, capsys, "--out", str(mine))
    assert rc == 0 and mine.read_text().endswith(out) and mine.read_text().startswith("<!-- written by hybrid-dyn")
    assert _compare(tmp_path, capsys, "--out", str(mine))[0] == 0  # its own file, unchanged: replaced
    mine.write_text(mine.read_text() + "\nmy conclusion\n")  # edited by the user: theirs now
    rc, _, err = _compare(tmp_path, capsys, "--out", str(mine))
    assert rc == 2 and "refusing to replace" in err and mine.read_text().endswith("my conclusion\n")
    rc, _, err = _compare(tmp_path, capsys, "--out", str(tmp_path / "nope" / "x.md"))
    assert rc == 2 and "does not exist" in err
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == ["a", "b", "mine.md", "notes.md"]
