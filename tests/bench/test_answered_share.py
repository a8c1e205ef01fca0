"""Refusing against erring in the report: a row that answered few test samples is marked and never headlined;
the estimator rows' refusals are NaN; the hardware-against-ideal section's ratios; the learned rows' inputs."""
import numpy as np

from hybrid_dyn.bench.analytic_rows import refusals_as_nan
from hybrid_dyn.bench.report import findings
from hybrid_dyn.bench.report_tables import LOW_ANSWER_MARK, best_row, task_tables
from hybrid_dyn.bench.hardware_vs_ideal import hardware_vs_ideal_lines


def _row(model, rmse, share, scenario="paper-ext", family="analytic", **kw):
    return {"task": "tip_force", "scenario": scenario, "model": model, "family": family, "status": "ok",
            "rmse": str(rmse), "answered_share": str(share), "rmse_refused_as_zero": str(kw.pop("as_zero", rmse)),
            "val_loss": "0.1", "test_loss": "0.1", "nmse": "0.1", **kw}


def test_a_row_answering_under_95_percent_is_marked_and_never_the_best():
    rows = [_row("kalman-fusion", 0.2, 0.43, as_zero=1.74), _row("base-wrench-tared", 0.5, 1.0),
            _row("momentum-observer", 0.4, 0.96)]
    best = best_row(rows, "tip_force", "paper-ext", lambda r: r["family"] == "analytic")
    assert best["model"] == "momentum-observer"  # the least RMSE among the rows answering >= 95 %
    md, tex = task_tables(rows, "tip_force")
    assert f"| kalman-fusion {LOW_ANSWER_MARK} | analytic |" in md and "| 43.0 % |" in md
    assert "| momentum-observer | analytic |" in md and "| 96.0 % |" in md
    # The refused-as-zero figure, labelled, beside the row's own.
    assert "`kalman-fusion` 43.0 % answered, 0.2000 (as zero: 1.7400)" in md
    assert r"\S{}" in tex
    text = "\n".join(findings(rows))
    assert "analytic (momentum-observer) 0.400" in text and "analytic (kalman-fusion)" not in text
    assert f"`kalman-fusion` {LOW_ANSWER_MARK} (answered 43.0 % of the test samples" in text


def test_a_report_without_the_column_reads_every_row_as_answering_everything():
    rows = [_row("base-wrench", 0.5, 1.0)]
    del rows[0]["answered_share"]
    assert best_row(rows, "tip_force", "paper-ext", lambda r: True)["model"] == "base-wrench"


def test_the_hardware_against_ideal_section_gives_each_rows_ratio():
    rows = [_row("rnea", 0.30, 1.0), _row("rnea", 0.12, 1.0, scenario="paper-ext-ideal"),
            _row("delan", 0.50, 1.0, family="delan"), _row("delan", 0.40, 1.0, scenario="paper-ext-ideal",
                                                             family="delan"),
            _row("only-here", 0.1, 1.0)]
    text = "\n".join(hardware_vs_ideal_lines(rows))
    assert "## Hardware sensors against ideal sensors" in text
    lines = [x for x in text.splitlines() if x.startswith("| rnea") or x.startswith("| delan")]
    assert lines[0].startswith("| rnea |") and "| 2.50 |" in lines[0]  # 0.30 / 0.12, the dearest first
    assert "| 1.25 |" in lines[1] and "only-here" not in text
    assert hardware_vs_ideal_lines([_row("rnea", 0.3, 1.0)]) == []  # no reference scenario: no section


def test_run_batchs_leading_zero_forces_are_refusals():
    f = np.zeros((6, 3))
    f[3:] = [[0.1, 0, 0], [0, 0, 0], [0.2, 0.1, 0]]
    out = refusals_as_nan(f)
    assert np.isnan(out[:3]).all() and np.array_equal(out[3:], f[3:])  # a later exact zero is an answer
    assert np.isnan(refusals_as_nan(np.zeros((4, 3)))).all()  # no window trusted: the whole run refused
    assert f[0, 0] == 0.0  # the input is left as it was


def test_learned_rows_read_the_logged_qd_and_its_derivative_never_the_simulators_qdd(tmp_path):
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.sim.executors import SerialExecutor
    from hybrid_dyn.sim.generator import generate_dataset
    from hybrid_dyn.sim.scenarios import scenario_config
    from hybrid_dyn.sim.sensors import causal_acceleration

    cfg = scenario_config("paper-ext", "quick", seed=5, n_instances=3, trajectories=(1, 1), standstill=0.3)
    ds = load_dataset(generate_dataset(cfg, tmp_path / "d", executor=SerialExecutor(), progress=False))
    inst = ds.split("train")[0]
    ws = ds.windows("train", 1, ["q", "qd", "qdd"], ["tau_m"])  # what a learned row is trained on
    x, _ = ws[np.arange(len(inst))]
    nv = inst.q.shape[1]
    np.testing.assert_array_equal(x[:, -1, nv:2 * nv], inst.qd.astype(x.dtype))  # qd as logged
    qdd = causal_acceleration(inst.qd, 1.0 / cfg.record_hz, cfg.qdd_cutoff_hz)  # the one derivative
    np.testing.assert_allclose(x[:, -1, 2 * nv:], qdd, rtol=1e-5, atol=1e-5)
    assert np.abs(x[:, -1, 2 * nv:] - inst.truth["qdd"]).max() > 1e-2  # not DART's acceleration
    assert np.abs(inst.qd - inst.truth["qd"]).max() > 0  # the drive's qd, not the simulator's
