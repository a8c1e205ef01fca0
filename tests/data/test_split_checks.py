"""Split settings of an import spec: refused in one line before the log is read,
and fractions that would leave a split empty refused by import and bench alike, nothing written."""
from __future__ import annotations

import pytest

from hybrid_dyn.data.data_checks import split_problems

from helpers.logs import write_log


@pytest.mark.parametrize("split, message", [
    ({"test_frac": 0}, "test_frac must lie strictly between 0 and 1"),
    ({"test_frac": -0.5}, "test_frac must lie strictly between 0 and 1"),
    ({"test_frac": 1}, "test_frac must lie strictly between 0 and 1"),
    ({"test_frac": 2}, "test_frac must lie strictly between 0 and 1"),
    ({"val_frac": 1.0}, "val_frac must lie strictly between 0 and 1"),
    ({"test_frac": "0.2"}, "test_frac must be a number, got '0.2'"),
    ({"val_frac": float("nan")}, "val_frac must be a number"),
    ({"seed": "abc"}, "split seed must be a non-negative integer, got 'abc'"),
    ({"seed": -1}, "split seed must be a non-negative integer"),
    ({"seed": True}, "split seed must be a non-negative integer"),
])
def test_bad_split_settings_are_refused_in_one_line_before_the_log_is_read(tmp_path, split, message):
    from hybrid_dyn.data.logs.importer import LogSpecError, spec_from_dict

    doc = {"name": "x", "robot": "panda", "source": {"files": ["missing.csv"]}, "time": {"sample_rate_hz": 100},
           "columns": {"q": "1-7", "tau_m": "8-14"}, "split": split}
    with pytest.raises(LogSpecError, match=message) as err:
        spec_from_dict(doc, base_dir=tmp_path)
    assert "\n" not in str(err.value)
    assert split_problems(0, 0.2, 0.2) == []


def test_split_fractions_that_leave_a_split_empty_are_refused_by_import_and_bench(tmp_path, capsys):
    """Finding 4: test_frac 0.99 left no training split (the bench failed in train_split_stats after writing
    run.json); n_blocks = 2 left val and test empty (import only warns: two trajectories cannot make three
    splits), and every bench row then failed with the same numpy message."""
    from hybrid_dyn.cli import main as cli_main

    spec = write_log(tmp_path / "logs", n=200)
    text = spec.read_text()
    spec.write_text(text.replace("seed = 0\n", "seed = 0\ntest_frac = 0.99\n"))
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "the train, val splits are empty" in err and "test_frac = 0.99" in err
    assert not (tmp_path / "a").exists()
    spec.write_text(text.replace("n_blocks = 10", "n_blocks = 2"))
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "b")]) == 0
    assert "only 2 trajectories" in capsys.readouterr().out
    out = tmp_path / "report"
    assert cli_main(["bench", "--data", str(tmp_path / "b"), "--out", str(out), "--rows", "rnea",
                     "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err
    assert "the val, test splits are empty" in err and str(tmp_path / "b") in err
    assert not out.exists() and not (tmp_path / "runs").exists()
