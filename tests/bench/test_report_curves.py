"""The report shows how each learned row's training ended: results.csv columns,
curves.json, a learning-curve figure per scenario, and epoch-capped rows flagged in the tables."""
import csv
import json

import pytest

from hybrid_dyn.bench.report import CAP_MARK, write_report
from hybrid_dyn.bench.catalog import ROWS, reference_label
from hybrid_dyn.bench.learned_rows import training_summary
from hybrid_dyn.bench.results import COLUMNS, CURVES_FILE, read_curves, read_results, write_curves, write_results

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _history(val_losses):
    return [{"epoch": k, "train_loss": 2.0 * v, "val_loss": v} for k, v in enumerate(val_losses)]


# ------------------------------------------------------------------ training_summary
def test_summary_derives_stop_and_best_epoch_for_models_that_lack_them():
    """Models trained before stopped_by/best_epoch were recorded: derived as their training loop decided."""
    old = {"history": _history([0.5, 0.3, 0.4]), "epochs": 3, "stopped_early": False, "initial_val_loss": 0.9}
    s = training_summary(old)
    assert (s["epochs"], s["stopped_by"], s["best_epoch"]) == (3, "epoch-cap", 1)
    assert s["history"] == old["history"] and s["initial_val_loss"] == 0.9
    # Early-stopped, and no epoch beat the untrained model (a residual that kept its physics part).
    s = training_summary({**old, "stopped_early": True, "initial_val_loss": 0.2})
    assert (s["stopped_by"], s["best_epoch"]) == ("patience", -1)
    # A diverged epoch (NaN) is never the one kept.
    s = training_summary({**old, "history": _history([float("nan"), 0.6, 0.7])})
    assert s["best_epoch"] == 1


def test_summary_carries_what_the_model_config_says():
    new = {"history": [{**h, "lr": 1e-3} for h in _history([0.5, 0.3, 0.4])], "epochs": 3,
           "stopped_early": True, "stopped_by": "lr-floor", "best_epoch": 2, "initial_val_loss": 0.9}
    s = training_summary(new)
    assert (s["epochs"], s["stopped_by"], s["best_epoch"]) == (3, "lr-floor", 2)  # not re-derived
    assert s["history"][0]["lr"] == 1e-3


def test_raw_sensor_reference_row_stays_in_the_seed_family():
    assert ROWS["seed-tip-11-raw"].family == "seed-net"
    assert reference_label("seed-tip-11-raw") == "raw sensor, untared: reference"
    assert reference_label("seed-tip-11") is None


# ------------------------------------------------------------------ the report, from files
def _row(model, family, rmse, **extra):
    row = {"task": "tip_force", "scenario": "syn", "model": model, "family": family, "inputs": "q, qd",
           "status": "ok", "val_loss": 0.1, "test_loss": 0.1, "rmse": rmse, "nmse": 0.1, "rmse_contact": rmse,
           "rmse_free": rmse, "max_error": 1.0, "rmse_1": rmse, "rmse_2": rmse, "rmse_3": rmse,
           "train_seconds": 1.0, "infer_us_per_sample": 1.0, "infer_us_per_call": 10.0, "n_params": 100,
           "n_test_samples": 50}
    row.update(extra)
    return row


def _learned_row(model, rmse, stopped_by, epochs, best_epoch):
    curve = {"task": "tip_force", "epochs": epochs, "stopped_by": stopped_by, "best_epoch": best_epoch,
             "initial_val_loss": 1.0, "history": _history([1.0 / (k + 2) for k in range(epochs)])}
    return _row(model, "seed-net", rmse, epochs=epochs, stopped_by=stopped_by, best_epoch=best_epoch, curve=curve)


def _table_line(md: str, model: str) -> list[str]:
    line = next(ln for ln in md.splitlines() if ln.startswith(f"| {model} "))
    return [c.strip() for c in line.strip("|").split("|")]


def test_report_flags_the_epoch_capped_row_and_draws_the_curves(tmp_path):
    rows = [_row("base-wrench", "analytic", 0.9),
            _learned_row("seed-tip-1", 0.8, "patience", 12, 6),
            _learned_row("seed-tip-5", 0.7, "epoch-cap", 30, 29),
            _learned_row("seed-tip-11-raw", 0.5, "patience", 8, 2)]
    write_results(tmp_path / "results.csv", rows)
    write_curves(tmp_path / CURVES_FILE, rows)
    # Redrawn from files alone: what read_results / read_curves give back.
    back = read_results(tmp_path / "results.csv")
    write_report(tmp_path, back, {"profile": {"name": "t", "scenarios": ["syn"]}, "wall_seconds": 1.0})

    by_model = {r["model"]: r for r in back}
    assert (by_model["seed-tip-5"]["epochs"], by_model["seed-tip-5"]["stopped_by"],
            by_model["seed-tip-5"]["best_epoch"]) == ("30", "epoch-cap", "29")
    assert (by_model["base-wrench"]["epochs"], by_model["base-wrench"]["stopped_by"],
            by_model["base-wrench"]["best_epoch"]) == ("", "", "")
    write_results(tmp_path / "again.csv", back)  # the columns round-trip
    assert (tmp_path / "again.csv").read_text() == (tmp_path / "results.csv").read_text()

    md = (tmp_path / "tip_force.md").read_text()
    header = _table_line(md, "model")
    col = header.index("epochs (stop)")
    assert _table_line(md, "seed-tip-5")[col] == f"30 (epoch-cap) {CAP_MARK}"
    assert _table_line(md, "seed-tip-1")[col] == "12 (patience)"
    assert _table_line(md, "base-wrench")[col] == "-"
    assert f"{CAP_MARK} Stopped by the epoch cap" in md and "Here: `seed-tip-5`." in md
    # The reference row is labelled, and is not its family's best in the summary despite its lower RMSE.
    assert "| seed-tip-11-raw (raw sensor, untared: reference) |" in md
    readme = (tmp_path / "README.md").read_text()
    assert "seed-net (seed-tip-5) 0.700 †" in readme and "seed-tip-11-raw) 0.5" not in readme
    # Each family's best carries its nMSE (here 0.1 for every row), so a net's share of the target's
    # variance reads beside its RMSE; the sentence says what the figure is.
    assert "seed-net (seed-tip-5) 0.700 † (0.100)" in readme and "RMSE [N] (nMSE)" in readme
    assert "1 is what predicting the mean gives" in readme
    assert "learning_curves_syn.png" in readme and "syn `seed-tip-5` (30 epochs)" in readme
    tex = (tmp_path / "tip_force.tex").read_text()
    assert "epochs (stop)" in tex and r"30 (epoch-cap) $^\dagger$" in tex

    assert (tmp_path / "learning_curves_syn.png").read_bytes()[:8] == PNG_MAGIC
    assert set(read_curves(tmp_path / CURVES_FILE)["syn"]) == {"seed-tip-1", "seed-tip-5", "seed-tip-11-raw"}


@pytest.mark.slow  # ~8 s alone, most of it importing torch and matplotlib
def test_tiny_bench_carries_the_model_config_into_the_report(tmp_path, panda):
    """A real (tiny) bench run: results.csv and curves.json say what each model's config.json says."""
    import dataclasses

    from hybrid_dyn.bench.profiles import PROFILES
    from hybrid_dyn.bench.runner import run_bench
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.learn import load_model

    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=4, n_samples=60, seed=3))
    profile = dataclasses.replace(
        PROFILES["quick"], name="tiny", scenarios=("synthetic",), families=(), rows=("base-wrench", "seed-tip-1"),
        workers=1, recipe="plateau",
        train=dict(max_epochs=1, batch_size=64, progress=False))  # one epoch, still improving: the cap stops it
    run_bench(profile, tmp_path / "report", work_root=tmp_path / "runs", dataset_provider=lambda s, p: ds,
              log=lambda m: None)

    with open(tmp_path / "report" / "results.csv", newline="") as f:
        written = {r["model"]: r for r in csv.DictReader(f)}
    assert list(next(iter(written.values()))) == COLUMNS
    model_dir, = (tmp_path / "runs").rglob("models/seed-tip-1")  # the cache's layout is the runner's business
    config = load_model(model_dir).config
    expected = training_summary(config)
    row = written["seed-tip-1"]
    assert row["status"] == "ok", row["error"]
    assert (int(row["epochs"]), row["stopped_by"], int(row["best_epoch"])) == \
        (expected["epochs"], expected["stopped_by"], expected["best_epoch"]) == (1, "epoch-cap", expected["best_epoch"])
    assert (written["base-wrench"]["epochs"], written["base-wrench"]["stopped_by"]) == ("", "")

    curves = json.loads((tmp_path / "report" / CURVES_FILE).read_text())
    assert list(curves) == ["synthetic"] and list(curves["synthetic"]) == ["seed-tip-1"]
    curve = curves["synthetic"]["seed-tip-1"]
    assert curve["history"] == config["history"] and curve["stopped_by"] == "epoch-cap"
    assert curve["task"] == "tip_force"
    assert (tmp_path / "report" / "learning_curves_synthetic.png").read_bytes()[:8] == PNG_MAGIC
    md = (tmp_path / "report" / "tip_force.md").read_text()
    assert "| 1 (epoch-cap" in md and CAP_MARK in md
