"""Studies over the harness: the data-scaling study on a tiny bench."""
import dataclasses
import json

import pytest

from hybrid_dyn.bench import profiles as profiles_mod
from hybrid_dyn.bench.runner import run_bench
from hybrid_dyn.bench.studies import Study, choose_rows, run_study
from hybrid_dyn.data.dataset import DatasetError
from hybrid_dyn.data.splits import first_instances
from hybrid_dyn.errors import UsageError


def test_first_instances_cuts_val_in_proportion_and_refuses_too_many():
    train, val = list(range(64)), list(range(100, 116))
    assert first_instances(train, val, 10) == (list(range(10)), [100, 101])  # 10 x 16 / 64 = 2.5 -> 2
    assert first_instances(train, val, 1)[1] == [100]  # never an empty val split
    assert first_instances(train, val, 64) == (train, val)
    with pytest.raises(DatasetError, match="65 training instances"):
        first_instances(train, val, 65)


def test_rows_are_chosen_on_validation_not_test():
    rows = [dict(scenario="s", task="joint_torque", model="seed-tau-mlp", family="seed-net", status="ok",
                 val_loss="0.2", rmse="1.0", n_params="100"),
            dict(scenario="s", task="joint_torque", model="seed-tau-lstm", family="seed-net", status="ok",
                 val_loss="0.1", rmse="9.0", n_params="100"),  # best on val, worst on test: it is chosen
            dict(scenario="s", task="joint_torque", model="rnea", family="analytic", status="ok",
                 val_loss="0.3", rmse="0.5", n_params=""),
            dict(scenario="s", task="joint_torque", model="identified-consistent", family="identified",
                 status="ok", val_loss="0.25", rmse="0.6", n_params="")]
    chosen = choose_rows(rows)
    assert chosen[("s", "joint_torque", "seed-net")]["model"] == "seed-tau-lstm"
    assert chosen[("s", "joint_torque", "physics")]["model"] == "identified-consistent"
    assert len(chosen) == 2  # the best physics row reads what the net reads: no second comparator


def test_a_learned_row_is_also_set_against_the_physics_row_on_its_own_inputs():
    """seed-sim: the best torque physics row reads the base wrench, the reference study's torque nets do not. Their fair
    comparator is the best physics row on q, qd, qdd (chosen on validation too); a row that reads the base
    wrench keeps the overall best."""
    def row(model, family, val, n_params=""):
        return dict(scenario="s", task="joint_torque", model=model, family=family, status="ok", val_loss=val,
                    rmse="1.0", n_params=n_params)

    chosen = choose_rows([row("seed-tau-mlp", "seed-net", "0.2", "100"), row("residual-rnea-bw", "residual", "0.1", "100"),
                          row("identified-bw-tared", "identified", "0.01"), row("rnea", "analytic", "0.5"),
                          row("identified-sigmoid-friction", "identified", "0.4")])
    assert chosen[("s", "joint_torque", "physics")]["model"] == "identified-bw-tared"
    assert chosen[("s", "joint_torque", "physics on q, qd, qdd")]["model"] == "identified-sigmoid-friction"
    assert len(chosen) == 4  # residual-rnea-bw reads the base wrench: its comparator is the overall best


@pytest.mark.slow
def test_data_scaling_study_on_a_tiny_bench(tmp_path, monkeypatch):
    tiny = dataclasses.replace(
        profiles_mod.PROFILES["quick"], name="tiny-scaling", families=("analytic",),
        rows=("seed-tau-mlp", "residual-rnea"),
        generator_overrides=dict(n_instances=6, trajectories=(1, 1)), scenario_overrides={},
        train=dict(budget_steps=20, budget_evals=2, batch_size=64), workers=1)
    monkeypatch.setitem(profiles_mod.PROFILES, "tiny-scaling", tiny)
    report, data, runs = tmp_path / "report", tmp_path / "data", tmp_path / "runs"
    study = Study(name="data-scaling", profile="tiny-scaling", description="", train_instances=(1, 2))
    with pytest.raises(UsageError, match="no bench report"):  # the full-data point comes first
        run_study(study, report, tmp_path / "out", work_root=runs, data_root=data, log=lambda m: None)
    full = run_bench(tiny, report, data_root=data, work_root=runs, log=lambda m: None)
    summary = run_study(study, report, tmp_path / "out", work_root=runs, data_root=data, log=lambda m: None)

    n_train = summary["full_train_instances"]
    assert summary["sizes"] == [1, 2, n_train] and n_train == 4  # 6 instances: 1 test, 1 val, 4 train
    panel = next(p for p in summary["panels"] if p["task"] == "joint_torque")
    lines = {line["family"]: line for line in panel["lines"]}
    # the best physics row reads the base wrench (rnea-bw); the MLP's fair comparator reads what it reads
    assert set(lines) == {"physics", "physics on q, qd, qdd", "seed-net", "residual"}
    assert lines["physics on q, qd, qdd"]["model"] == "rnea" and lines["physics"]["model"] != "rnea"
    for physics in ("physics", "physics on q, qd, qdd"):
        assert len(set(lines[physics]["rmse"])) == 1  # learns nothing from the training instances
    full_rmse = {r["model"]: float(r["rmse"]) for r in full if r["task"] == "joint_torque"}
    for family in ("seed-net", "residual"):
        rmse = lines[family]["rmse"]
        # the last point is the profile's own report (results.csv keeps 4 significant digits)
        assert rmse[-1] == pytest.approx(full_rmse[lines[family]["model"]], rel=1e-3)
        assert all(v is not None and v > 0 for v in rmse)
    # The variants' nets really saw fewer instances: their saved configs say so, and the one-instance
    # MLP is not the full one.
    configs = [json.loads(p.read_text()) for p in runs.rglob("models/seed-tau-mlp/config.json")]
    seen = sorted(c["train_config"]["train_instances"] or 0 for c in configs)
    assert seen == [0, 1, 2], seen
    assert lines["seed-net"]["rmse"][0] != lines["seed-net"]["rmse"][-1]
    text = (tmp_path / "out" / "README.md").read_text()
    assert "N = 1" in text and (tmp_path / "out" / "data_scaling.png").stat().st_size > 0
