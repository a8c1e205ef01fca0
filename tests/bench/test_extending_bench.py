"""Extending the bench (docs/extending.md): a family and a row, each declared in one place, reach the
results, the report's tables, ``compare`` and every list derived from the family's metadata."""
import csv
import dataclasses
import shutil

import numpy as np
import pytest

from hybrid_dyn.bench import report as report_mod
from hybrid_dyn.bench.catalog import select_rows
from hybrid_dyn.bench.compare import compare_reports
from hybrid_dyn.bench.families import FAMILIES, Family
from hybrid_dyn.bench.plan import BenchPlan
from hybrid_dyn.bench.profiles import PROFILES, PROFILES_FILE, read_profiles
from hybrid_dyn.bench.rows import ROWS, Predictor, Row
from hybrid_dyn.cli import main as cli_main


def _mean_torque(ds, ctx) -> Predictor:
    """A cheap model: every sample's torque is the train split's mean [Nm] (nothing but numpy)."""
    mean = np.concatenate([i["tau_m"] for i in ds.split("train")]).mean(axis=0)
    return Predictor(predict=lambda insts: [np.tile(mean, (len(i), 1)) for i in insts],
                     single_call=lambda inst, k: mean, inputs="nothing")


@pytest.fixture
def toy_family_and_row():
    """The family and the row, each one declaration; withdrawn after the test."""
    family = FAMILIES.register(Family("toy-net", "a toy learned family (tests)", fitted=True, in_studies=True,
                                      figures=("traces",)))
    row = ROWS.register(Row("toy-mean-torque", "joint_torque", "toy-net", needs=("q", "tau_m"), needs_urdf=False,
                      build=_mean_torque))
    try:
        yield family, row
    finally:
        ROWS.unregister(row.name)
        FAMILIES.unregister(family.name)
    assert family.name not in FAMILIES.names(in_studies=True)  # withdrawn: the derived lists forget it


def _profile_rows(profiles) -> dict:
    """Each profile's rows, as its plan selects them (names, in run order)."""
    return {p.name: [r.name for r in BenchPlan(p).selected_rows()] for p in profiles}


def test_a_declared_family_is_in_the_lists_read_from_its_metadata(toy_family_and_row):
    assert "toy-net" in FAMILIES.names(in_studies=True) and "toy-net" in FAMILIES.names(fitted=True, in_studies=True)
    assert "toy-net" not in FAMILIES.names(physics_informed=True)
    assert [r.name for r in select_rows(families=("toy-net",))] == ["toy-mean-torque"]


def test_a_new_family_in_the_studies_changes_no_shipped_profile():
    """A family declared in_studies (and a row in it) before the profiles are read (as a plugin's or a user's
    module is) leaves every shipped profile's rows and run.json record as they were."""
    before = _profile_rows(PROFILES.values())
    recorded = {name: p.to_dict() for name, p in PROFILES.items()}
    family = FAMILIES.register(Family("toy-extra", "a toy family (tests)", fitted=True, in_studies=True))
    row = ROWS.register(Row("toy-extra-row", "joint_torque", "toy-extra", needs=("q", "tau_m"), needs_urdf=False,
                            build=_mean_torque))
    try:
        reread = read_profiles(PROFILES_FILE)  # the shipped TOML read again, the toy family now declared
        assert [p.name for p in reread] == list(PROFILES)
        assert _profile_rows(reread) == before
        assert {p.name: p.to_dict() for p in reread} == recorded
        assert all("toy-extra-row" not in rows for rows in before.values())
    finally:
        ROWS.unregister(row.name)
        FAMILIES.unregister(family.name)


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
