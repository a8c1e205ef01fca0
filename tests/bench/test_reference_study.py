"""The reference study's (Kruzic et al. 2021) Tables 2 and 3 as a report section: our figure, its, and their ratio,
row by row."""

from hybrid_dyn.bench.reference_study import REFERENCE_TABLE2, REFERENCE_TABLE3, reference_comparison_text


def _row(model, task, rmse, family="seed-net"):
    return dict(scenario="seed-sim", task=task, model=model, family=family, status="ok", rmse=str(rmse),
                epochs="40", stopped_by="budget")


def test_no_seed_net_no_section():
    assert reference_comparison_text([_row("rnea", "joint_torque", 0.9, family="analytic")]) is None


def test_each_seed_net_row_beside_the_studys_figure_with_the_ratio():
    tip_study = REFERENCE_TABLE2["seed-tip-4"][2]
    tau_study = REFERENCE_TABLE3[("seed-tau-mlp", "sim-ext")][2]
    rows = [_row("seed-tip-4", "tip_force", 2 * tip_study), _row("seed-tau-mlp", "joint_torque", 3 * tau_study),
            _row("rnea", "joint_torque", 0.5, family="analytic")]
    text = reference_comparison_text(rows)
    tip_line = next(line for line in text.splitlines() if line.startswith("| 4 |"))
    assert f"{2 * tip_study:.4f}" in tip_line and f"{tip_study:.4f}" in tip_line and "| 2.00 |" in tip_line
    tau_line = next(line for line in text.splitlines() if line.startswith("| seed-tau-mlp |"))
    assert "| 3.00 |" in tau_line
    assert "`rnea` 0.5000 Nm" in text  # the physics bar on the same test split
