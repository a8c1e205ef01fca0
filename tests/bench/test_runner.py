"""hybrid_dyn.bench.run_record: what run.json records of where the data were."""
import os
from pathlib import Path

from hybrid_dyn.bench.run_record import recorded_path


def test_a_dataset_path_is_recorded_relative_to_the_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert recorded_path(tmp_path / "data" / "seed-sim-x") == os.path.join("data", "seed-sim-x")
    assert recorded_path(Path("data/x")) == os.path.join("data", "x")  # as given
    outside = tmp_path.parent / "elsewhere" / "d"
    assert recorded_path(outside) == os.path.join("..", "elsewhere", "d")
    assert not any(Path(recorded_path(p)).is_absolute() for p in (tmp_path / "a", outside))
