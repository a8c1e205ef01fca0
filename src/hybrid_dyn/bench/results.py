"""The bench's files beside its report: results.csv (one row per task, scenario and model, stable
columns) and curves.json (the learned rows' loss curves), written atomically and read back, so that
the report can be drawn from files (``report.py``)."""
from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import numpy as np

from ..outputs import unique_temp

COLUMNS = [
    "task", "scenario", "model", "family", "inputs", "status",
    "val_loss", "test_loss", "rmse", "nmse", "rmse_contact", "rmse_free", "max_error",
    "rmse_1", "rmse_2", "rmse_3", "rmse_4", "rmse_5", "rmse_6", "rmse_7", "noise_rms",
    "train_seconds", "infer_us_per_sample", "infer_us_per_call", "n_params", "n_test_samples",
    "epochs", "stopped_by", "best_epoch",  # learned rows only (``training_summary``); empty for analytic rows
    "prior_kept",  # hybrid rows only: where validation kept the physics prior ("all", "none", "joints 2, 5")
    "sigma_coverage",  # estimator rows: share of test samples with an error bar within 2 sigma on every axis
    "error",
    "notes",  # what the row's numbers cannot show, " | "-separated (row_checks.py): undefined nMSE, untested motion
    # CPU time [s]: training (the model file's record, or the fit in the bench's process) and
    # scoring (predicting val and test, the metrics, the timed single calls). Last: a report written
    # before them lacks them, read as "not recorded".
    "train_cpu_seconds", "score_cpu_seconds",
    # The share of the test samples the row answered (a refusal: NaN predictions, metrics.answered); every
    # error figure above is over the answered ones. rmse_refused_as_zero: the RMSE with each refusal scored as
    # a zero prediction (what the bench scored before). Last, as above: older reports lack them.
    "answered_share", "rmse_refused_as_zero",
]
# The statuses of a scored row (numbers, stored predictions): "implausible" is an identified row whose parameters
# are outside the robot's bounds (row_checks.py): in the tables with its note, never a family's best.
SCORED_STATUSES = ("ok", "implausible")


def write_results(path: Path, rows: list[dict], columns: list | None = None) -> None:
    """results.csv with the stable column set (or ``columns``: a report's own, redrawn), written atomically."""
    columns = COLUMNS if columns is None else list(columns)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = unique_temp(path)
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: _fmt(r.get(k, "")) for k in columns})
    os.replace(tmp, path)


CURVES_FILE = "curves.json"  # beside results.csv: the learned rows' loss curves


def write_curves(path: Path, rows: list[dict]) -> None:
    """The learned rows' loss curves, ``{scenario: {model: {task, epochs, stopped_by, best_epoch,
    initial_val_loss, history}}}`` (``training_summary``), written atomically, so the report's learning-curve
    figures can be redrawn from files."""
    curves: dict = {}
    for r in rows:
        if r.get("curve") is not None:
            curves.setdefault(r["scenario"], {})[r["model"]] = r["curve"]
    write_json(Path(path), curves)


def read_curves(path: Path) -> dict:
    """curves.json as ``write_curves`` wrote it; {} when there is none (a report without learned rows)."""
    path = Path(path)
    return json.loads(path.read_text()) if path.is_file() else {}


def read_results(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def results_columns(path: Path) -> list[str]:
    """The header of a results.csv (a report written before a column was added lacks it)."""
    with open(path, newline="") as f:
        return next(csv.reader(f), [])


def _fmt(v):
    if isinstance(v, float):
        return "" if np.isnan(v) else f"{v:.6g}"
    return v


def write_json(path: Path, obj: dict) -> None:
    """A JSON file (run.json, curves.json) written atomically."""
    tmp = unique_temp(path)
    tmp.write_text(json.dumps(obj, indent=1, default=str))
    os.replace(tmp, path)
