"""Splits of an imported log: at random, in time order, or as the spec lists them.

The time-order property is checked on the written dataset's own sample times (each
instance's ``t`` and its source file), not on the split function's output.
"""
from pathlib import Path

import numpy as np
import pytest

from hybrid_dyn.data import import_log, load_dataset
from hybrid_dyn.data.logs.importer import LogSpecError, read_spec
from hybrid_dyn.data.splits import SplitSpecError

from helpers.logs import CSV_COLUMNS, sine_log, write_csv


def _time_order_violations(path) -> list[str]:
    """Per source log: test samples earlier than a train (or val) sample, and val samples earlier than a
    train sample. Read from the dataset's instances (their t and source), independent of the importer."""
    ds = load_dataset(path)
    source = {r["name"]: r["source"] for r in ds.meta["instances"]}
    out = []
    for log in sorted(set(source.values())):
        t = {s: [np.asarray(i.t) for i in ds.split(s) if source[i.name] == log] for s in ("train", "val", "test")}
        first = {s: min((x.min() for x in v), default=np.inf) for s, v in t.items()}
        last = {s: max((x.max() for x in v), default=-np.inf) for s, v in t.items()}
        for early, late in (("train", "test"), ("val", "test"), ("train", "val")):
            if first[late] < last[early]:
                out.append(f"{log}: a {late} sample at t = {first[late]:.2f} s precedes a {early} sample "
                           f"at t = {last[early]:.2f} s")
    return out


def _spec(tmp_path, files, split: str, n_blocks=10) -> Path:
    spec = tmp_path / "log.toml"
    spec.write_text('name = "arm"\n[source]\nfiles = [' + ", ".join(f'"{f}"' for f in files) + ']\n'
                    '[time]\ncolumn = "t"\n[trajectories]\nfrom = "blocks"\n'
                    f'n_blocks = {n_blocks}\n'
                    '[columns]\n' + "".join(f"{k} = {v!r}\n".replace("'", '"') for k, v in CSV_COLUMNS.items())
                    + "[split]\n" + split)
    return spec


@pytest.fixture
def one_log(tmp_path):
    log = sine_log(n=1500)
    keep = np.setdiff1d(np.arange(1500), np.arange(700, 712))  # a gap: block 4 becomes two segments
    write_csv(tmp_path / "run.csv", {k: (v[keep] if k in ("t", "q", "qd", "tau") else v) for k, v in log.items()})
    return tmp_path / "run.csv"


def test_time_split_never_puts_a_test_sample_before_a_training_sample(tmp_path, one_log):
    import_log(_spec(tmp_path, [one_log], 'by = "time"\n'), tmp_path / "ds")
    ds = load_dataset(tmp_path / "ds")
    assert _time_order_violations(tmp_path / "ds") == []
    traj = ds.meta["trajectory_splits"]
    assert traj == {"train": [f"run_b{k:02d}" for k in range(6)], "val": ["run_b06", "run_b07"],
                    "test": ["run_b08", "run_b09"]}  # 60/20/20 of the log's 15 s, in time order
    # The block with the gap is two instances, both in train.
    assert sorted(n for n in ds.meta["splits"]["train"] if n.startswith("run_b04")) == ["run_b04_s00", "run_b04_s01"]
    test_t = np.concatenate([i.t for i in ds.split("test")])
    # 1488 rows in 10 blocks of 149 or 148: the last two start at row 1192, t = (1192 + 12) / 100 s.
    assert test_t.min() == pytest.approx(12.04, abs=1e-9) and test_t.max() == pytest.approx(14.99, abs=1e-6)
    assert "time order" in ds.meta["split"]["text"] and ds.meta["split"]["by"] == "time"


def test_the_time_order_check_finds_a_random_split_out(tmp_path, one_log):
    """The default (random) split of the same log puts test blocks before training blocks (seed 0: the
    first and the last block): the check above can fail."""
    import_log(_spec(tmp_path, [one_log], "seed = 0\n"), tmp_path / "ds")
    assert load_dataset(tmp_path / "ds").meta["trajectory_splits"]["test"] == ["run_b00", "run_b09"]
    assert any("test sample" in v for v in _time_order_violations(tmp_path / "ds"))


def test_time_split_of_several_logs_keeps_each_log_in_time_order(tmp_path):
    a = write_csv(tmp_path / "a.csv", sine_log(n=1000, seed=1))
    b = write_csv(tmp_path / "b.csv", sine_log(n=1000, seed=2))
    import_log(_spec(tmp_path, [a, b], 'by = "time"\n', n_blocks=5), tmp_path / "ds")
    ds = load_dataset(tmp_path / "ds")
    assert _time_order_violations(tmp_path / "ds") == []
    assert {len(v) for v in ds.meta["trajectory_splits"].values()} == {2, 6}  # 6 train, 2 val, 2 test of 10
    assert {ds.instances[n].t[0] for n in ds.meta["splits"]["test"]} == {8.0}  # both logs' last blocks


def test_listed_split_is_written_as_listed_and_checked(tmp_path, one_log):
    lists = ('train = ["run_b00", "run_b01", "run_b02", "run_b03", "run_b04", "run_b05", "run_b06"]\n'
             'val = ["run_b07"]\ntest = ["run_b08", "run_b09"]\n')
    spec = _spec(tmp_path, [one_log], lists)
    assert read_spec(spec).split_by == "list"
    import_log(spec, tmp_path / "ds")
    ds = load_dataset(tmp_path / "ds")
    assert ds.meta["trajectory_splits"]["val"] == ["run_b07"] and ds.meta["splits"]["val"] == ["run_b07"]
    assert _time_order_violations(tmp_path / "ds") == []
    with pytest.raises(SplitSpecError, match=r"in no split: \['run_b09'\]"):
        import_log(_spec(tmp_path, [one_log], lists.replace(', "run_b09"', "")), tmp_path / "ds2")
    with pytest.raises(SplitSpecError, match=r"not trajectories of the log: \['run_b10'\]"):
        import_log(_spec(tmp_path, [one_log], lists.replace("run_b09", "run_b10")), tmp_path / "ds2")
    with pytest.raises(SplitSpecError, match="more than one place"):
        import_log(_spec(tmp_path, [one_log], lists.replace('"run_b07"', '"run_b06"')), tmp_path / "ds2")
    assert not (tmp_path / "ds2").exists()


@pytest.mark.parametrize("split,match", [
    ('by = "chronological"\n', "by must be one of"),
    ('by = "time"\ntest = ["run_b09"]\n', "lists of trajectories are given"),
    ('by = "list"\n', "needs the trajectories of each split"),
    ('train = "run_b00"\n', "must be a list of trajectory names"),
])
def test_bad_split_sections_are_refused_before_reading(tmp_path, split, match):
    with pytest.raises(LogSpecError, match=match):
        read_spec(_spec(tmp_path, ["absent.csv"], split))
