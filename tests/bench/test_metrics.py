"""Benchmark metrics on hand-computed cases, and the results file's contract."""
import numpy as np
import pytest

from hybrid_dyn.bench.metrics import ErrorReport, nmse, rmse, rmse_per_component, standardized_mse
from hybrid_dyn.bench.results import COLUMNS, read_results, write_results


def test_rmse_hand_computed():
    pred = np.array([[1.0, 2.0], [3.0, 4.0]])
    target = np.array([[0.0, 2.0], [3.0, 2.0]])
    # errors 1, 0, 0, 2 -> mean square 5/4
    assert rmse(pred, target) == pytest.approx(np.sqrt(5 / 4))
    np.testing.assert_allclose(rmse_per_component(pred, target), [np.sqrt(1 / 2), np.sqrt(4 / 2)])


def test_nmse_is_mse_over_variance():
    target = np.array([[0.0], [2.0], [4.0]])  # variance 8/3
    pred = target + np.array([[1.0], [-1.0], [1.0]])  # MSE 1
    assert nmse(pred, target) == pytest.approx(3 / 8)
    assert nmse(np.full_like(target, target.mean()), target) == pytest.approx(1.0)  # predicting the mean


def test_standardized_mse():
    assert standardized_mse(np.array([[2.0]]), np.array([[0.0]]), np.array([5.0]), np.array([2.0])) == pytest.approx(1.0)


def test_contact_and_free_split_at_one_newton():
    f_true = np.array([[0.0, 0.0, 0.5], [0.0, 3.0, 0.0], [0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    target = f_true
    pred = f_true + np.array([[1.0, 0, 0], [0, 0, 2.0], [1.0, 0, 0], [0, 0, 2.0]])
    rep = ErrorReport.compute(pred, target, f_true)
    assert rep.rmse_free == pytest.approx(np.sqrt(2 / 6))  # samples 0 and 2: one 1.0 error each
    assert rep.rmse_contact == pytest.approx(np.sqrt(8 / 6))  # samples 1 and 3: one 2.0 error each
    assert rep.max_error == pytest.approx(2.0)


def test_partly_nan_or_infinite_predictions_are_an_error_not_a_refusal():
    with pytest.raises(ValueError, match="NaN on some components only"):
        ErrorReport.compute(np.array([[np.nan, 1.0]]), np.array([[0.0, 0.0]]))
    with pytest.raises(ValueError, match="1 are inf"):
        ErrorReport.compute(np.array([[np.inf, 1.0]]), np.array([[0.0, 0.0]]))


def test_refused_samples_are_scored_apart_from_the_answered_ones():
    # Five samples of two components; the first two refused (NaN on every component).
    pred = np.array([[np.nan, np.nan], [np.nan, np.nan], [1.0, 2.0], [0.0, -1.0], [3.0, 3.0]])
    target = np.array([[4.0, 0.0], [0.0, 2.0], [0.0, 2.0], [0.0, 0.0], [1.0, 3.0]])
    rep = ErrorReport.compute(pred, target)
    # By hand: answered errors (1, 0), (0, -1), (2, 0): squares 1 + 1 + 4 = 6 over 6 entries.
    assert rep.answered_share == pytest.approx(3 / 5) and rep.n_samples == 5
    assert rep.rmse == pytest.approx(1.0)
    np.testing.assert_allclose(rep.per_component, [np.sqrt(5 / 3), np.sqrt(1 / 3)])
    assert rep.max_error == pytest.approx(2.0)
    # Refused as zero: the two refusals add 16 + 4 to the 6, over 10 entries.
    assert rep.rmse_refused_as_zero == pytest.approx(np.sqrt(26 / 10))
    # The contact split counts the answered samples alone (truth |F| > 1 N on samples 0, 2 and 4).
    truth = np.array([[5.0, 0, 0], [0, 0, 0], [2.0, 0, 0], [0, 0, 0], [0, 3.0, 0]])
    rep = ErrorReport.compute(pred, target, truth)
    assert rep.rmse_contact == pytest.approx(np.sqrt((1 + 4) / 4)) and rep.rmse_free == pytest.approx(np.sqrt(1 / 2))
    # Nothing refused: the two figures agree; everything refused: no error figure, nothing answered.
    full = ErrorReport.compute(target + 1.0, target)
    assert full.answered_share == 1.0 and full.rmse == full.rmse_refused_as_zero == pytest.approx(1.0)
    none = ErrorReport.compute(np.full_like(target, np.nan), target)
    assert none.answered_share == 0.0 and np.isnan(none.rmse)


def test_results_csv_has_the_stable_columns(tmp_path):
    rows = [{"task": "tip_force", "scenario": "s", "model": "base-wrench", "status": "ok", "rmse": 0.1234567891},
            {"task": "joint_torque", "scenario": "s", "model": "delan", "status": "failed", "error": "boom"}]
    write_results(tmp_path / "results.csv", rows)
    back = read_results(tmp_path / "results.csv")
    assert list(back[0]) == COLUMNS
    for col in ("task", "scenario", "model", "inputs", "val_loss", "test_loss", "rmse", "nmse", "rmse_contact",
                "rmse_free", "max_error", "train_seconds", "infer_us_per_sample", "infer_us_per_call", "n_params"):
        assert col in COLUMNS
    assert back[0]["rmse"] == "0.123457" and back[1]["error"] == "boom"


class _FakeInstance(dict):
    def __init__(self, measured, truth):
        super().__init__(base_wrench=measured)
        self.truth = {"base_wrench": truth}


def test_base_force_noise_rms_recovers_a_known_white_noise_under_a_bias():
    from hybrid_dyn.bench.metrics import base_force_noise_rms

    rng = np.random.default_rng(0)
    insts = []
    for _ in range(3):
        truth = rng.normal(0, 5, (20000, 6))
        bias = rng.uniform(-2, 2, 6)  # a per-run offset: a tare removes it, so it is not noise
        insts.append(_FakeInstance(truth + bias + 0.2 * rng.standard_normal((20000, 6)), truth))
    assert abs(base_force_noise_rms(insts) - 0.2) < 0.004  # 60,000 x 3 draws: the RMS is within 1 %
    no_truth = _FakeInstance(np.zeros((5, 6)), None)
    no_truth.truth = {}
    assert np.isnan(base_force_noise_rms([no_truth]))


def test_nmse_and_loss_over_a_zero_variance_component_are_undefined_not_dropped():
    """A joint whose torque is 0 throughout was dropped from the nMSE in silence (the row
    was headlined at nMSE 0.015) and its losses, standardised by a floored std, read 4.9e13. Both are undefined
    (NaN) now, and the component is named; with the component live the same errors give the hand-computed
    values."""
    target = np.array([[0.0, 0.0], [2.0, 0.0], [4.0, 0.0]])  # component 1: variance 8/3; component 2: dead
    pred = target + np.array([[1.0, 3.0], [-1.0, 3.0], [1.0, 3.0]])
    assert np.isnan(nmse(pred, target))  # not 3/8, the live component's alone
    assert nmse(pred[:, :1], target[:, :1]) == pytest.approx(3 / 8)
    assert np.isnan(standardized_mse(pred, target, np.zeros(2), np.array([1.0, 0.0])))
    assert standardized_mse(pred, target, np.zeros(2), np.array([1.0, 3.0])) == pytest.approx((1 + 1) / 2)
    assert np.isnan(ErrorReport.compute(pred, target).nmse)
    from hybrid_dyn.bench.metrics import zero_variance_components

    assert zero_variance_components(target) == [1]  # the bench names it beside the row
