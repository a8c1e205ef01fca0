"""The hardware sensor model on the bench: the analytic rows on contact-steps-hardware run at the dataset's encoder
resolution (0 for the legacy sensor model, so today's rows are unchanged) and report their error
bar's coverage (``sigma_coverage`` in results.csv, from run_batch's ``with_sigma``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from hybrid_dyn.bench.plan import BenchPlan
from hybrid_dyn.analytic.batch_run import run_batch
from hybrid_dyn.analytic.tare import TARE_SECONDS, tare_samples
from hybrid_dyn.bench import analytic_rows
from hybrid_dyn.bench.analytic_rows import refusals_as_nan
from hybrid_dyn.bench.catalog import ROWS
from hybrid_dyn.bench.profiles import PROFILES, BenchProfile
from hybrid_dyn.bench.results import read_results, results_columns, write_results
from hybrid_dyn.bench.plan import BenchContext
from hybrid_dyn.bench.scoring import score_row, train_split_stats
from hybrid_dyn.data import load_dataset
from hybrid_dyn.sim.executors import SerialExecutor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.scenarios import scenario_config
from helpers.legacy_sensors import legacy

SIGMA = 0.5  # N per axis, the fake error bar


@pytest.fixture(scope="module")
def hardware_ds(tmp_path_factory):
    """Three short instances of contact-steps-hardware (one per split)."""
    cfg = scenario_config("contact-steps-hardware", "quick", seed=1, n_instances=3, trajectories=(1, 1),
                          standstill=0.6)
    return load_dataset(generate_dataset(cfg, tmp_path_factory.mktemp("hw") / "ds", executor=SerialExecutor(),
                                         progress=False))


def _ctx(ds, panda, tmp_path, logs):
    return BenchContext(BenchProfile(name="t", scenarios=("contact-steps-hardware",)), "contact-steps-hardware", ds,
                        panda, tmp_path / "work", tmp_path / "data", log=logs.append)


def test_the_default_profile_runs_the_analytic_rows_on_the_hardware_scenario(hardware_ds):
    prof = PROFILES.lookup("default")
    assert "contact-steps-hardware" in prof.scenarios
    ds = SimpleNamespace(fields=list(hardware_ds.fields), meta=hardware_ds.meta)
    applied = {s.family for s in BenchPlan(prof).selected_rows() if BenchPlan(prof).applies(s, ds)}
    assert applied == {"analytic"}
    assert {"base-wrench", "base-momentum", "kalman-fusion"} <= {s.name for s in BenchPlan(prof).selected_rows()
                                                                 if BenchPlan(prof).applies(s, ds)}


def test_the_rows_read_the_datasets_encoder_resolution(hardware_ds, panda):
    ctx = lambda meta: SimpleNamespace(dataset=SimpleNamespace(meta=meta), robot=panda)  # noqa: E731
    assert analytic_rows._encoder_resolution(ctx(hardware_ds.meta)) == 1e-5  # the Panda's description
    legacy = scenario_config("paper-ext-ideal", "default").to_dict()
    assert analytic_rows._encoder_resolution(ctx({"config": legacy})) == 0.0  # today's rows unchanged
    assert analytic_rows._encoder_resolution(ctx({})) == 0.0  # an imported log: q as recorded


def test_a_legacy_datasets_rows_read_q_and_qd_as_recorded(panda, tmp_path):
    """contact-steps (the legacy white-noise sensors): the row's RMSE is run_batch's with exact encoders
    (encoder_resolution=0, today's rows), not the joint-state filter's the estimator defaults to."""
    cfg = scenario_config("contact-steps", "quick", seed=2, n_instances=3, trajectories=(1, 1), standstill=0.6,
                          **legacy("contact-steps"))
    ds = load_dataset(generate_dataset(cfg, tmp_path / "cs", executor=SerialExecutor(), progress=False))
    row = score_row(ROWS["base-momentum"], _ctx(ds, panda, tmp_path, []), train_split_stats(ds))
    rmse = {}
    for res in (0.0, "auto"):
        # Over the answered samples: the window's (and the observer's first) zeros are refusals.
        err = np.concatenate([refusals_as_nan(run_batch("base-momentum", panda, 1000.0, i.q, i.qd, i.base_wrench,
                                                        encoder_resolution=res)[0]) - i.truth["tip_force"]
                              for i in ds.split("test")])
        rmse[res] = float(np.sqrt(np.nanmean(err ** 2)))
    assert abs(rmse[0.0] - rmse["auto"]) > 1e-3  # the two readings differ: the test can tell them apart
    assert row["rmse"] == pytest.approx(rmse[0.0], rel=1e-9)
    # Each test run refuses at least its window and the observer's first (zero) output; the share counts them.
    refused = np.concatenate([np.isnan(refusals_as_nan(run_batch("base-momentum", panda, 1000.0, i.q, i.qd,
                                                                 i.base_wrench, encoder_resolution=0.0)[0])).all(1)
                              for i in ds.split("test")])
    assert refused.sum() >= len(ds.split("test")) * (tare_samples(1000.0, TARE_SECONDS) + 1)
    assert row["answered_share"] == pytest.approx(1 - refused.mean(), rel=1e-12)


def test_the_coverage_column_is_the_share_within_two_sigma(hardware_ds, panda, tmp_path, monkeypatch):
    """Through a run_batch with the error bar (the real one's forces, a fixed 0.5 N sigma): the
    column is the share of test samples after the window whose error is within 1 N on all three axes,
    counted here; it reaches results.csv through write_results."""
    seen = []

    def with_sigma(method, robot, rate_hz, q, qd, base_wrench=None, tau_J=None, tare_seconds=0.5, value=None,
                   stream=None, encoder_resolution=None, with_sigma=False):
        seen.append((encoder_resolution, with_sigma))
        forces, used = run_batch(method, robot, rate_hz, q, qd, base_wrench, tau_J, tare_seconds, value, stream,
                                 encoder_resolution=encoder_resolution)
        return (forces, used, np.full(forces.shape, SIGMA)) if with_sigma else (forces, used)

    monkeypatch.setattr(analytic_rows, "run_batch", with_sigma)
    logs = []
    ctx = _ctx(hardware_ds, panda, tmp_path, logs)
    row = score_row(ROWS["base-momentum"], ctx, train_split_stats(hardware_ds))
    assert seen and set(seen) == {(1e-5, True)}
    n = tare_samples(1000.0, TARE_SECONDS)
    inside = []
    for inst in hardware_ds.split("test"):
        forces, _ = run_batch("base-momentum", panda, 1000.0, inst.q, inst.qd, inst.base_wrench, encoder_resolution=1e-5)
        inside.append(np.all(np.abs(forces - inst.truth["tip_force"])[n:] <= 2 * SIGMA, axis=1))
    expected = float(np.mean(np.concatenate(inside)))
    assert 0.0 < expected < 1.0  # a share the rows could get wrong either way
    assert row["sigma_coverage"] == pytest.approx(expected, abs=1e-12)
    write_results(tmp_path / "results.csv", [row])
    assert "sigma_coverage" in results_columns(tmp_path / "results.csv")
    assert float(read_results(tmp_path / "results.csv")[0]["sigma_coverage"]) == pytest.approx(expected, rel=1e-5)


def test_the_estimators_error_bar_reaches_the_column(hardware_ds, panda, tmp_path):
    """The real run_batch's sigma: the column equals the share counted here from run_batch's own output, over
    the samples that have an error bar (inf before the estimator's first settled estimate)."""
    row = score_row(ROWS["base-momentum"], _ctx(hardware_ds, panda, tmp_path, []), train_split_stats(hardware_ds))
    n = tare_samples(1000.0, TARE_SECONDS)
    inside = []
    for inst in hardware_ds.split("test"):
        forces, _, sigma = run_batch("base-momentum", panda, 1000.0, inst.q, inst.qd, inst.base_wrench,
                                     encoder_resolution=1e-5, with_sigma=True)
        assert sigma.shape == forces.shape and np.all(sigma[n:] > 0)
        settled = np.isfinite(sigma[n:]).all(axis=1)
        assert settled.mean() > 0.9  # the estimate settles soon after the window
        inside.append(np.all(np.abs(forces - inst.truth["tip_force"])[n:] <= 2 * sigma[n:], axis=1)[settled])
    expected = float(np.mean(np.concatenate(inside)))
    assert 0.0 < expected <= 1.0 and row["sigma_coverage"] == pytest.approx(expected, abs=1e-12)
