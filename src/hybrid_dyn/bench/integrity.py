"""Whose report folder, and whose numbers.

- **The marker.** A folder is a bench report only if its ``run.json`` carries ``"bench_report": 1`` and
  a profile the bench recorded (a mapping): the bench writes that before anything else. A user's
  ``run.json`` with a ``profile`` key (``{"profile": "my-experiment"}``) is not one, and ``bench`` and
  ``report`` refuse the folder before writing anything (:func:`read_run_json`, the one test both use).
- **The digest.** After every row the bench records in run.json a digest of results.csv: one sha256 per
  row (of the row as read back) and one of the file, and one of run.json's other fields
  (:func:`results_digest`).
- **The check.** ``hybrid-dyn report`` recomputes every error figure of every scored row from
  predictions.h5 (the stored test predictions and targets, ``metrics.ErrorReport``), and checks every
  row of results.csv against the digest (the figures predictions.h5 cannot give: losses, timings), and
  run.json's fields against theirs (the datasets, profile and times the README quotes).
  A row that differs is an error naming the row and the column (:func:`verify_results`); a report
  without a digest (written before reports carried one) is refused, never printed unverified.
"""
from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
import numbers
from pathlib import Path

import numpy as np

from ..errors import HybridDynError
from ..outputs import json_marker, refuse_foreign
from .metrics import ErrorReport
from .results import SCORED_STATUSES, read_results

RUN_FILE = "run.json"
RESULTS_FILE = "results.csv"
DIGEST_KEY = "results_digest"
# run.json's record of the files the report wrote (tables, figures, README): all ``report`` ever removes
# (a stale figure), and what a bench taking the folder over for another profile clears.
REPORT_FILES = "report_files"
# results.csv columns that predictions.h5 gives again (``score_row``'s ErrorReport on the test split).
RECOMPUTED = ("rmse", "nmse", "rmse_contact", "rmse_free", "max_error", "n_test_samples")
TARGETS = {"tip_force": "tip_force", "joint_torque": "tau_m"}  # rows.TASK_TARGET, without importing the rows


class ReportIntegrityError(HybridDynError, ValueError):
    """A report's files disagree: a results.csv row that is not what the bench computed, or a run.json
    of another report; the message names the row."""


def is_bench_meta(doc) -> bool:
    """Whether ``doc`` (a parsed run.json) carries the marker the bench writes when it claims a folder."""
    return isinstance(doc, dict) and doc.get("bench_report") == 1 and isinstance(doc.get("profile"), dict)


def recorded_profile(prof: dict) -> dict:
    """A run.json's ``profile`` in today's names, to compare with ``BenchProfile.to_dict()``: a training
    recipe recorded under its former name (``default``, ``seed``) is the same recipe renamed
    (``learn.recipes.RECIPE_ALIASES``), so that a rerun still recognises its own report."""
    from ..learn.recipes import RECIPE_ALIASES

    if isinstance(prof, dict) and prof.get("recipe") in RECIPE_ALIASES:
        return {**prof, "recipe": RECIPE_ALIASES[prof["recipe"]]}
    return prof


def same_profile(recorded: dict, profile) -> bool:
    """Whether a run.json's ``profile`` is ``profile`` (a ``BenchProfile``): the same data, rows and
    recipe. The method ``notes`` are left out: they describe the run and may be corrected (e.g. a
    renamed recipe) without making a report another profile's."""
    def identity(d):
        return {k: v for k, v in d.items() if k != "notes"} if isinstance(d, dict) else d

    return identity(recorded_profile(recorded)) == identity(profile.to_dict())


def read_run_json(out_dir, replacing: bool = True) -> dict | None:
    """The run.json of report folder ``out_dir``; None when there is none; refused when it is not the
    bench's (unreadable, or without the marker): ``OutputPathError`` for a command that would write
    there, ``ReportIntegrityError`` for one that only reads it (``replacing`` False: ``compare``)."""
    path = Path(out_dir) / RUN_FILE
    if not path.is_file():
        return None
    doc = json_marker(path, "bench_report", 1)  # read as every command reads its marker (outputs.py)
    if not is_bench_meta(doc):
        why = "it is not a run.json of hybrid-dyn bench (it lacks the 'bench_report': 1 marker and the recorded profile)"
        if not replacing:
            raise ReportIntegrityError(f"{path}: {why}; {Path(out_dir)} is not a bench report")
        refuse_foreign(path, "benchmark report", why)
    return doc


def row_key(row: dict) -> str:
    return f"{row.get('scenario')} / {row.get('task')} / {row.get('model')}"


def _row_digest(row: dict) -> str:
    return hashlib.sha256(json.dumps(row, sort_keys=True).encode()).hexdigest()


def results_digest(path, meta: dict) -> dict:
    """The digest run.json records: of results.csv at ``path`` (its sha256 and one per row, as read back)
    and of run.json's own other fields (``meta`` as written), so that neither is edited or swapped alone."""
    path = Path(path)
    return {"sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
            "rows": {row_key(r): _row_digest(r) for r in read_results(path)}, "run": run_digest(meta)}


def run_digest(meta: dict) -> str:
    """sha256 of run.json's fields but the digest, as JSON reads them back (tuples as lists, paths as text)."""
    doc = json.loads(json.dumps({k: v for k, v in meta.items() if k != DIGEST_KEY}, default=str))
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def check_meta(meta: dict, path) -> None:
    """The run.json fields the report reads, with the types the bench writes (a hand edit such as
    ``"wall_seconds": "x"`` is one error here, not a traceback in the README's formatting)."""
    def bad(key, want):
        raise ReportIntegrityError(f"{path}: {key} must be {want}, got {meta.get(key)!r}")

    if meta.get("wall_seconds") is not None and not _is_number(meta["wall_seconds"]):
        bad("wall_seconds", "a number of seconds or null")
    for key, kind, want in (("invocations", list, "a list"), ("skipped", list, "a list"),
                            ("datasets", dict, "a mapping"), ("machine", dict, "a mapping")):
        if meta.get(key) is not None and not isinstance(meta[key], kind):
            bad(key, want)
    for inv in meta.get("invocations") or []:
        if not isinstance(inv, dict) or (inv.get("wall_seconds") is not None and not _is_number(inv["wall_seconds"])):
            bad("invocations", "a list of {wall_seconds: seconds, ...}")
    for k in meta.get("skipped") or []:
        if not isinstance(k, dict) or not all(isinstance(k.get(f), str) for f in ("scenario", "task", "model", "reason")):
            bad("skipped", "a list of {scenario, task, model, reason}")
    if not all(isinstance(d, dict) for d in (meta.get("datasets") or {}).values()):
        bad("datasets", "a mapping of scenario to {path, checksum, ...}")
    scenarios = meta.get("scenarios")
    if scenarios is not None and not (isinstance(scenarios, (dict, list)) and all(isinstance(k, str) for k in scenarios)):
        bad("scenarios", "a mapping of scenario label to dataset, or a list of labels")
    prof = meta["profile"]
    for key, ok, want in PROFILE_FIELDS:  # those the README quotes; each may be absent (older reports)
        if prof.get(key) is not None and not ok(prof[key]):
            raise ReportIntegrityError(f"{path}: profile.{key} must be {want}, got {prof[key]!r}")
    requested = meta.get("requested")
    if requested is not None and not _texts(requested):
        bad("requested", "a list of rows (scenario / task / model)")
    files = meta.get(REPORT_FILES)
    if files is not None and not (isinstance(files, list) and all(is_plain_name(f) for f in files)):
        bad(REPORT_FILES, "a list of file names in the report folder")
    machine = meta.get("machine")
    if machine is not None and not (all(k in machine for k in ("machine", "processor", "python"))
                                    and isinstance(machine.get("packages"), dict)):
        bad("machine", "{machine, processor, python, packages}")


_text = lambda x: isinstance(x, str)  # noqa: E731
_texts = lambda x: isinstance(x, list) and all(isinstance(v, str) for v in x)  # noqa: E731
PROFILE_FIELDS = (("name", _text, "text"), ("generator_profile", _text, "text"), ("recipe", _text, "text"),
                  ("robot", _text, "text"), ("params", _text, "text"), ("tool", _text, "text"),
                  ("scenarios", _texts, "a list of text"), ("notes", _texts, "a list of text"),
                  ("train", lambda x: isinstance(x, dict), "a mapping"),
                  ("seed", lambda x: _is_number(x) and float(x).is_integer(), "an integer"))


def is_plain_name(name) -> bool:
    """A file name inside the folder, nothing else: the report deletes by these names."""
    return isinstance(name, str) and name not in ("", ".", "..") and "/" not in name and "\\" not in name \
        and not name.startswith(".") and name != RUN_FILE


def _is_number(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def verify_results(rows: list[dict], meta: dict, preds, where) -> None:
    """Refuse ``rows`` (results.csv read back) unless every one is what the bench recorded (run.json's
    digest) and every scored row's error figures are those of its stored predictions (``preds``:
    ``Predictions`` of predictions.h5, or None where it is absent or unreadable)."""
    digest = meta.get(DIGEST_KEY)
    if not isinstance(digest, dict) or not isinstance(digest.get("rows"), dict):
        raise ReportIntegrityError(f"{where}/run.json records no digest of results.csv (a report written before "
                                   "reports carried one, or run.json replaced): its numbers cannot be checked; rerun the bench "
                                   "(cached datasets and models are reused)")
    recorded = digest["rows"]
    for r in rows:
        key = row_key(r)
        if key not in recorded:
            raise ReportIntegrityError(f"{where}/results.csv row {key} is not one the bench recorded in run.json "
                                       "(another report's run.json, or a row added by hand)")
        if _row_digest(r) != recorded[key]:
            raise ReportIntegrityError(f"{where}/results.csv row {key} differs from what the bench wrote (run.json "
                                       f"digest){_first_difference(r, preds)}")
    missing = sorted(set(recorded) - {row_key(r) for r in rows})
    if missing:
        raise ReportIntegrityError(f"{where}/results.csv lacks rows the bench recorded in run.json: {missing[:3]}")
    if digest.get("run") != run_digest(meta):  # the datasets, profile and times the README quotes
        raise ReportIntegrityError(f"{where}/run.json differs from what the bench wrote (an edited field, or "
                                   "parts of another report's run.json): its datasets and profile cannot be quoted")
    if preds is None:
        return
    for r in rows:
        if r.get("status") in SCORED_STATUSES:
            recomputed = _recompute(r, preds)
            if recomputed is None:
                raise ReportIntegrityError(f"{where}/predictions.h5 holds no predictions of row {row_key(r)} "
                                           "(a predictions.h5 of another report?)")
            for col, value in recomputed.items():
                if not _same(r.get(col), value):
                    raise ReportIntegrityError(f"{where}: row {row_key(r)}: results.csv says {col} = {r.get(col)!r}, "
                                               f"its stored predictions give {value:.6g}")


def _first_difference(row: dict, preds) -> str:
    """A hint for the error: the first figure that predictions.h5 gives otherwise, if any."""
    if preds is None or row.get("status") not in SCORED_STATUSES:
        return ""
    recomputed = _recompute(row, preds) or {}
    for col, value in recomputed.items():
        if not _same(row.get(col), value):
            return f": {col} = {row.get(col)!r}, its stored predictions give {value:.6g}"
    return ""


def _recompute(row: dict, preds) -> dict | None:
    """The error figures of ``row`` from its stored test predictions; None when predictions.h5 has none."""
    pred = preds.get(row.get("scenario"), row.get("task"), row.get("model"))
    target = TARGETS.get(row.get("task"))
    test = preds.test(row.get("scenario"))
    if pred is None or target is None or not test or any(target not in i for i in test) or len(pred) != len(test):
        return None
    truth = (np.concatenate([i.get("tip_force_truth", i["tip_force"]) for i in test])
             if all("tip_force" in i for i in test) else None)
    try:
        rep = ErrorReport.compute(np.concatenate(pred), np.concatenate([i[target] for i in test]), truth)
    except ValueError:  # shapes that do not match: not this row's predictions
        return None
    out = {"rmse": rep.rmse, "nmse": rep.nmse, "rmse_contact": rep.rmse_contact, "rmse_free": rep.rmse_free,
           "max_error": rep.max_error, "n_test_samples": float(rep.n_samples)}
    out.update({f"rmse_{j + 1}": float(v) for j, v in enumerate(rep.per_component)})
    if "answered_share" in row:  # a report written before the column lacks it
        out.update(answered_share=rep.answered_share, rmse_refused_as_zero=rep.rmse_refused_as_zero)
    return out


def _same(text, value: float) -> bool:
    """Whether a results.csv cell (6 significant digits, '' for NaN) holds ``value``."""
    if not math.isfinite(value):
        return text in ("", None, "nan")
    try:
        cell = float(text)
    except (TypeError, ValueError):
        return False
    return math.isclose(cell, value, rel_tol=1e-5, abs_tol=1e-300)


@dataclasses.dataclass
class CheckedReport:
    """A report folder's files as the bench wrote them: run.json (``meta``), results.csv (``rows``) and
    predictions.h5 (``preds``: ``Predictions``, or None where it is absent or unreadable)."""

    meta: dict
    rows: list
    preds: object


def read_checked_report(out_dir, replacing: bool = True) -> CheckedReport:
    """Read and check a bench report folder as ``hybrid-dyn report`` does before it draws anything, and as
    ``compare`` does before it prints a number: the marker (:func:`read_run_json`; ``replacing`` as
    there), run.json's fields (:func:`check_meta`), and every row of results.csv against run.json's digest
    and predictions.h5 (:func:`verify_results`). Any failure is one error naming the file, row or field."""
    from ..errors import OutputPathError
    from .predictions import PREDICTIONS_FILE, Predictions, PredictionsError

    out_dir = Path(out_dir)
    if not (out_dir / RUN_FILE).is_file() or not (out_dir / RESULTS_FILE).is_file():
        raise OutputPathError(f"{out_dir} is not a bench report folder: it needs run.json and results.csv "
                              "(written by hybrid-dyn bench)")
    meta = read_run_json(out_dir, replacing=replacing)
    check_meta(meta, out_dir / RUN_FILE)
    rows = _read_rows(out_dir / RESULTS_FILE)
    try:
        preds = Predictions(out_dir / PREDICTIONS_FILE)
    except PredictionsError:  # absent or unreadable: the digest alone vouches for the rows (the report notes it)
        preds = None
    verify_results(rows, meta, preds, out_dir)
    return CheckedReport(meta, rows, preds)


def _read_rows(path: Path) -> list[dict]:
    """results.csv's rows; a file that is not a table of the bench's shape is one error, not a traceback
    (a row with more or fewer cells than the header has a None key or value, which no digest can take)."""
    try:
        rows = read_results(path)
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        raise ReportIntegrityError(f"{path} does not read as a results table: {err}") from None
    for line, r in enumerate(rows, start=2):
        if None in r or None in r.values():
            raise ReportIntegrityError(f"{path} line {line}: its cells do not match the header's columns "
                                       "(not what the bench wrote)")
    return rows
