"""End-to-end: the bench command's machinery on a tiny generated scenario, every family once."""
import csv
import dataclasses

import pytest

from hybrid_dyn.bench.catalog import ROWS
from hybrid_dyn.bench.profiles import PROFILES
from hybrid_dyn.bench.results import COLUMNS
from hybrid_dyn.bench.runner import run_bench

pytestmark = pytest.mark.system


@pytest.mark.slow
def test_tiny_bench_writes_every_row_and_column(tmp_path):
    quick = PROFILES["quick"]
    tiny = dataclasses.replace(
        quick, name="tiny",
        # tiny for real: quick's own 30 mismatch-ext instances would override the 3 (the residual GP's
        # fit alone then took 350 s of this test)
        generator_overrides=dict(n_instances=3, trajectories=(1, 1)), scenario_overrides={},
        families=("analytic", "identified"),
        rows=("seed-tip-1", "seed-tip-11", "residual-basewrench", "residual-momentum",
              "seed-tau-lstm", "residual-rnea", "residual-rnea-bw", "delan", "delan-friction", "delan-residual"),
        train=dict(budget_steps=2, budget_evals=1, batch_size=64, progress=False),
        workers=2,  # exercises the parallel generator and the training pool
    )
    rows = run_bench(tiny, tmp_path / "report", data_root=tmp_path / "data", work_root=tmp_path / "runs",
                     log=lambda m: None)
    with open(tmp_path / "report" / "results.csv", newline="") as f:
        written = list(csv.DictReader(f))
    assert list(written[0]) == COLUMNS
    names = {(r["task"], r["model"]) for r in written}
    expected = {("tip_force", m) for m in ("torques-pinv", "base-wrench", "momentum-observer", *tiny.rows[:4])}
    expected |= {("joint_torque", m) for m in ("rnea", "rnea-bw", *tiny.rows[4:])}
    assert expected <= names
    failed = [(r["model"], r["error"]) for r in written if r["status"] != "ok"]
    assert not failed
    for r in written:
        # A row that refused every test sample (kalman-fusion's start-up check on these short runs with an
        # undeclared tool) has no error over answered samples: its share says so, and its refused-as-zero
        # figure is still there.
        answered = float(r["answered_share"])
        scored = ("val_loss", "test_loss", "rmse", "max_error") if answered > 0 else ()
        if not answered:
            assert r["rmse"] == "" and float(r["rmse_refused_as_zero"]) >= 0.0, r["model"]
        for col in (*scored, "infer_us_per_sample", "infer_us_per_call"):
            assert r[col] != "" and float(r[col]) >= 0.0, (r["model"], col)
        assert r["inputs"], r["model"]
        # A trained net (residuals on identified models included); the residual GP has parameters but no epochs.
        learned = ROWS.lookup(r["model"]).trains
        assert learned == (int(r["n_params"] or 0) > 0 and r["model"] != "gp-residual-identified"), r["model"]
        assert (r["stopped_by"] == "budget") == learned, (r["model"], r["stopped_by"])
    for name in ("README.md", "tip_force.md", "joint_torque.md", "tip_force.tex", "joint_torque.tex",
                 "rmse_by_family_tip_force.png", "traces_tip_force_mismatch-ext.png",
                 "curves.json", "learning_curves_mismatch-ext.png"):
        assert (tmp_path / "report" / name).is_file(), name
    assert "training: recipe `budget`" in (tmp_path / "report" / "README.md").read_text()  # the profile's recipe
    # A rerun reuses the cached dataset and trained models rather than redoing them.
    rows2 = run_bench(tiny, tmp_path / "report", data_root=tmp_path / "data", work_root=tmp_path / "runs",
                      log=lambda m: None)
    by_model = {(r["task"], r["model"]): r for r in rows2}
    for r in rows:
        if r["family"] != "analytic":
            assert by_model[(r["task"], r["model"])]["rmse"] == pytest.approx(r["rmse"])
