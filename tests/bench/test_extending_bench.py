"""Extending the bench (docs/extending.md): a family and a row, each declared in one place, reach the
results, the report's tables, ``compare`` and every list derived from the family's metadata."""
import csv
import dataclasses
import shutil

import numpy as np
import pytest

from hybrid_dyn.bench import report as report_mod
from hybrid_dyn.bench.compare import compare_reports, compared_families
from hybrid_dyn.bench.profiles import PROFILES, BenchProfile
from hybrid_dyn.bench.rows import FAMILIES, ROWS, Family, Predictor, Row, declare, family_names, study_families
from hybrid_dyn.bench.studies import learned_study_families
from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.deprecation import DeprecatedNameWarning


def _mean_torque(ds, ctx) -> Predictor:
    """A cheap model: every sample's torque is the train split's mean [Nm] (nothing but numpy)."""
    mean = np.concatenate([i["tau_m"] for i in ds.split("train")]).mean(axis=0)
    return Predictor(predict=lambda insts: [np.tile(mean, (len(i), 1)) for i in insts],
                     single_call=lambda inst, k: mean, inputs="nothing")


@pytest.fixture
def toy_family_and_row():
    """The family and the row, each one declaration; withdrawn after the test."""
    family = FAMILIES.register(Family("toy-net", "a toy learned family (tests)", learned=True, in_studies=True,
                                      figures=("traces",)))
    row = declare(Row("toy-mean-torque", "joint_torque", "toy-net", needs=("q", "tau_m"), needs_urdf=False,
                      build=_mean_torque))
    try:
        yield family, row
    finally:
        ROWS.unregister(row.name)
        FAMILIES.unregister(family.name)
    assert family.name not in study_families()  # withdrawn: the derived lists forget it


def test_a_declared_family_is_in_every_derived_list(toy_family_and_row):
    assert "toy-net" in study_families() and "toy-net" in learned_study_families()
    assert "toy-net" in compared_families() and "toy-net" not in family_names(physics_informed=True)
    assert BenchProfile(name="t", scenarios=("s",)).families[-1] == "toy-net"  # a profile's default families
    with pytest.warns(DeprecatedNameWarning, match="compared_families"):
        from hybrid_dyn.bench import compare
        assert "toy-net" in compare.LEARNED


def test_a_toy_row_runs_and_reaches_results_report_and_compare(toy_family_and_row, tmp_path, panda, monkeypatch,
                                                               capsys):
    from hybrid_dyn.bench.runner import run_bench
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset

    # The figures are matplotlib's slow part and not what this test reads.
    monkeypatch.setattr(report_mod, "_figures", lambda *a, **k: [])
    monkeypatch.setattr(report_mod, "learning_curve_figures", lambda *a, **k: [])
    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=3, n_samples=40, seed=1))
    profile = dataclasses.replace(PROFILES["quick"], name="toy", scenarios=("synthetic",), families=("toy-net",),
                                  rows=("rnea",), workers=1)
    a, b = tmp_path / "a", tmp_path / "b"
    run_bench(profile, a, work_root=tmp_path / "runs", dataset_provider=lambda s, p: ds, log=lambda m: None)

    with open(a / "results.csv", newline="") as f:
        rows = {r["model"]: r for r in csv.DictReader(f)}
    assert (rows["toy-mean-torque"]["family"], rows["toy-mean-torque"]["status"]) == ("toy-net", "ok")

    assert cli_main(["report", str(a)]) == 0  # the tables redrawn from the files, as a user does
    capsys.readouterr()
    assert "| toy-mean-torque | toy-net | nothing |" in (a / "joint_torque.md").read_text()

    shutil.copytree(a, b)  # a second report of the same rows: the toy row against its own report's physics
    text = compare_reports(a, b)
    line = next(x for x in text.splitlines() if x.startswith("| toy-mean-torque |"))
    assert line.startswith("| toy-mean-torque | toy-net |") and line.endswith("| 1.00x |")
