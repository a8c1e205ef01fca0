"""The benchmark report: tables laid out like the reference study's (Kruzic et al. 2021), LaTeX, figures, README.

Everything here is drawn from the bench's files in the report folder, never from
a live run: results.csv (``results.py``), curves.json, run.json and predictions.h5
(``predictions.py``), so ``hybrid-dyn report DIR`` redraws the same report without
retraining or re-simulating. The headline findings are computed from those numbers,
never typed. The project's own acceptance floors are not here: they are a check
of their own (``checks/acceptance.py``), since they mean nothing on a user's data.

The tables are drawn in ``report_tables.py``, the figures in ``report_figures.py``; this module
writes the README around them (what was run, the findings, convergence, the files) and redraws a
whole report from its folder.
"""
from __future__ import annotations

import json
import math
import platform
from pathlib import Path

from ..data import package_versions
from .catalog import reference_label
from .predictions import PREDICTIONS_FILE, Predictions, PredictionsError
from .hybrids import hybrid_lines
from .free_motion import section_lines as free_motion_section
from .hardware_vs_ideal import hardware_vs_ideal_lines
from .report_figures import _figures, learning_curve_figures
from .report_tables import (CAP_MARK, IMPLAUSIBLE_MARK, LOW_ANSWER_MARK, _cap_mark, _contenders, _is_capped, _ok,
                            answered_share, low_answer, notes_by_text, task_tables)
from .results import SCORED_STATUSES
from .row_checks import IMPLAUSIBLE
from .report_tables import best_row  # noqa: F401  (re-exported: imported from here, e.g. checks/acceptance.py)
from .results import CURVES_FILE, read_curves
from .reference_study import REFERENCE_COMPARISON_FILE, reference_comparison_text


# ------------------------------------------------------------------- findings
def _nmse_note(row) -> str:
    """The row's nMSE as " (0.123)", or "" where it has none."""
    try:
        return f" ({float(row['nmse']):.3f})"
    except (KeyError, TypeError, ValueError):
        return ""


def findings(rows) -> list[str]:
    """Headline sentences, each computed from the rows."""
    lines = []
    for scenario in dict.fromkeys(r["scenario"] for r in rows):
        for task, unit in (("tip_force", "N"), ("joint_torque", "Nm")):
            fams = {}
            for r in _contenders(rows):
                if r["task"] == task and r["scenario"] == scenario:
                    if r["family"] not in fams or float(r["rmse"]) < float(fams[r["family"]]["rmse"]):
                        fams[r["family"]] = r
            if not fams:
                continue
            ranked = sorted(fams.values(), key=lambda r: float(r["rmse"]))
            desc = ", ".join(f"{r['family']} ({r['model']}) {float(r['rmse']):.3f}{_cap_mark(r)}{_nmse_note(r)}"
                             for r in ranked)
            lines.append(f"- **{scenario}, {task.replace('_', ' ')}** — best per family, RMSE [{unit}] "
                         f"(nMSE): {desc}.")
            lines += _headline_notes(rows, ranked, scenario, task)
    if lines:
        # Beside physics a net's RMSE can read as "learning is broken"; the nMSE says how much it learned.
        lines.append("- nMSE: the test MSE over the test target's variance, per axis or joint, then averaged: "
                     "1 is what predicting the mean gives, 0 is exact. Every joint weighs the same, so a wrist joint "
                     "with little torque variance counts as much as the shoulder, and nMSE can rank rows "
                     "differently from RMSE.")
    return lines


def _headline_notes(rows, ranked, scenario, task) -> list[str]:
    """Under a headline: the notes of its rows (what their numbers cannot show) and the rows left out of it
    because their identified parameters are implausible (both were once headlined in silence)."""
    lines = [f"  - note: {n} — " + ", ".join(f"`{r['model']}`" for r in rs)
             for n, rs in notes_by_text(ranked).items()]
    out = [r["model"] for r in rows
           if r["scenario"] == scenario and r["task"] == task and r.get("status") == IMPLAUSIBLE]
    if out:
        lines.append(f"  - not a family's best: {', '.join(f'`{m}` {IMPLAUSIBLE_MARK}' for m in out)}, identified "
                     f"parameters outside the robot's bounds (the bodies are named under `{task}.md`)")
    few = [r for r in rows if r["scenario"] == scenario and r["task"] == task and low_answer(r)]
    if few:
        def over_answered(r) -> str:  # a row that refused every sample has no RMSE to give
            return f"RMSE {float(r['rmse']):.3f} over those" if r.get("rmse") not in (None, "") else "no RMSE"

        lines.append("  - not a family's best: " + ", ".join(
            f"`{r['model']}` {LOW_ANSWER_MARK} (answered {100 * answered_share(r):.1f} % of the test samples, "
            f"{over_answered(r)})" for r in few)
            + ": refused the rest (its table lists them)")
    return lines


def convergence_lines(rows, curve_figures: list[str]) -> list[str]:
    """The README's convergence section: how each learned row stopped, the capped rows named."""
    trained = [r for r in _ok(rows) if r.get("stopped_by") not in (None, "")]
    if not trained:
        return []
    counts = {}
    for r in trained:
        counts[r["stopped_by"]] = counts.get(r["stopped_by"], 0) + 1
    lines = ["", "## Convergence of the learned rows", "",
             f"- stopped by: {', '.join(f'{k} {v}' for k, v in sorted(counts.items()))} (of {len(trained)} learned rows); "
             "the `epochs (stop)` column of each table and `epochs`, `stopped_by`, `best_epoch` in results.csv"]
    if curve_figures:
        lines.append("- learning curves, train and validation loss per epoch with the kept epoch marked (from "
                     "`curves.json`): " + ", ".join(f"`{f}`" for f in curve_figures))
    capped = [r for r in trained if _is_capped(r)]
    if capped:
        lines.append(f"- {CAP_MARK} stopped by the epoch cap while still improving, so they may not have converged: "
                     + ", ".join(f"{r['scenario']} `{r['model']}` ({r.get('epochs')} epochs)" for r in capped))
    refs = sorted({r["model"] for r in trained if reference_label(r["model"])})
    if refs:
        lines.append("- reference rows, in the tables but never a family's best here: "
                     + ", ".join(f"`{m}` ({reference_label(m)})" for m in refs))
    return lines


# --------------------------------------------------------------------- README
def machine_info() -> dict:
    """What run.json records of the machine a bench ran on (the README quotes it)."""
    return {"machine": platform.machine(), "processor": platform.processor() or platform.system(),
            "python": platform.python_version(), "packages": package_versions()}


def _command(prof: dict) -> str:
    """The command line that wrote a report, from its profile (run.json)."""
    from .plan import is_dataset_path

    scenarios = prof.get("scenarios") or []
    if prof.get("name") == "data" and scenarios and all(is_dataset_path(s) for s in scenarios):
        return "hybrid-dyn bench " + " ".join(f"--data {s}" for s in scenarios)
    from .profiles import PROFILES

    cmd = f"hybrid-dyn bench --profile {prof.get('name', '?')}"
    named = PROFILES.get(prof.get("name"))
    if named is not None:  # the options that narrowed the named profile (bench/cli.py)
        base = named.to_dict()
        if list(scenarios) != base["scenarios"]:
            cmd += f" --scenarios {','.join(scenarios)}"
        if prof.get("families") != base["families"] or prof.get("rows") != base["rows"]:
            cmd += f" --families {','.join(prof.get('families') or [])}" if prof.get("families") else ""
            cmd += f" --rows {','.join(prof.get('rows') or [])}" if prof.get("rows") else ""
    return cmd


def write_report(out_dir, rows, meta: dict, log=print) -> list[str]:
    """Write the tables (``.md``, ``.tex``), the figures and README.md into ``out_dir`` from ``rows`` (as
    results.csv holds them: ``results.read_results``), ``meta`` (run.json), curves.json and predictions.h5
    there. Returns the notes on what could not be drawn (a figure without its predictions), also logged."""
    from .integrity import REPORT_FILES
    from .run_record import record_report_files, remove_report_files

    out_dir = Path(out_dir)
    written = ["README.md"]
    for task in ("tip_force", "joint_torque"):
        md, tex = task_tables(rows, task)
        (out_dir / f"{task}.md").write_text(md)
        (out_dir / f"{task}.tex").write_text(tex)
        written += [f"{task}.md", f"{task}.tex"]
    notes_out = []
    try:
        preds = Predictions(out_dir / PREDICTIONS_FILE)
    except PredictionsError as err:
        preds = None
        notes_out.append(f"traces and error-vs-force figures not drawn: {err}")
    prof = meta.get("profile", {})
    figures = _figures(out_dir, rows, preds, seed=int(prof.get("seed") or 0))
    curve_figures = learning_curve_figures(out_dir, read_curves(out_dir / CURVES_FILE))
    figures += curve_figures
    failed = [r for r in rows if r.get("status") not in SCORED_STATUSES]
    lines = _what_was_run(meta, prof, rows)
    notes = prof.get("notes") or []
    if notes:
        lines += ["", "## Method notes", ""] + [f"- {n}" for n in notes]
    lines += ["", "## Headline findings", ""] + findings(rows)
    if any(_is_capped(r) for r in _contenders(rows)):
        lines += ["", f"{CAP_MARK}: stopped by the epoch cap while still improving; it may not have converged "
                      "(see the learning curves)."]
    lines += hybrid_lines(rows)
    lines += hardware_vs_ideal_lines(rows)
    lines += convergence_lines(rows, curve_figures)
    reference_text = reference_comparison_text(rows, read_curves(out_dir / CURVES_FILE))
    if reference_text is not None:  # the reference study's nets are in this report: its tables beside ours
        (out_dir / REFERENCE_COMPARISON_FILE).write_text(reference_text)
        written.append(REFERENCE_COMPARISON_FILE)
        lines += ["", "## The seed's tables", "", f"`{REFERENCE_COMPARISON_FILE}`: the seed's Tables 2 and 3 (Kruzic "
                  "et al. 2021, another simulator) row by row beside this report's seed nets, the architecture "
                  "ordering in both, and each net's training and validation loss at the kept round."]
    lines += free_motion_section(out_dir)  # written beside the bench by benchmarks/free_motion.py, kept on a redraw
    lines += _left_out_lines(meta, notes_out, failed)
    lines += _files_lines(out_dir, preds, reference_text, curve_figures, figures)
    (out_dir / "README.md").write_text("\n".join(lines))
    # What an earlier report recorded and this one no longer draws (a figure of another dataset) is removed;
    # nothing else is: a user's file named like a figure was never recorded, so it is never removed.
    written += figures
    remove_report_files(out_dir, [f for f in meta.get(REPORT_FILES) or [] if f not in written])
    record_report_files(out_dir, meta, written)
    for note in notes_out:
        log(f"[report] {note}")
    return notes_out


def unfinished(meta: dict) -> bool:
    """Whether the bench's last invocation did not finish (killed, interrupted: run.json records no end)."""
    invocations = meta.get("invocations") or []
    return bool(invocations) and "finished" in invocations[-1] and invocations[-1]["finished"] is None


def _unfinished_lines(meta: dict, rows) -> list[str]:
    """The README's first words on a report whose bench did not finish: which requested rows never ran."""
    if not unfinished(meta):
        return []
    from .integrity import row_key

    done = {row_key(r) for r in [*rows, *(meta.get("skipped") or [])]}
    requested = meta.get("requested")
    if requested is None:
        missing = "run.json does not record which rows were requested (a bench of an older version)"
    else:
        never = [k for k in requested if k not in done]
        missing = (f"{len(never)} of the {len(requested)} rows requested never ran: "
                   + ", ".join(f"`{k}`" for k in never) if never else "every row requested ran")
    return [f"**Incomplete: the last invocation of the bench (started {meta['invocations'][-1].get('started', '?')}) "
            f"did not finish** (killed or interrupted; the tables hold only the rows it finished). {missing}. "
            "Rerun the same command to finish it (cached datasets and models are reused).", ""]


def _what_was_run(meta: dict, prof: dict, rows=()) -> list[str]:
    """The README's title, provenance and "What was run" section: scenarios, training, machine, datasets."""
    machine = meta.get("machine")
    labels = meta.get("scenarios") or {s: s for s in prof.get("scenarios", [])}
    command = _command(prof)
    no_machine = ("the bench records it when an invocation finishes, and this one did not" if unfinished(meta)
                  else "a report written before it was")
    lines = [
        f"# Benchmark report: profile `{prof.get('name', '?')}`", "", *_unfinished_lines(meta, rows),
        f"Produced by `{command}`; every number below and in the "
        "tables was computed by that command on this data (`hybrid-dyn report` redraws it only after checking "
        "every row against the digest the bench recorded in run.json and the stored predictions). Seed (Kruzic et al. 2021) figures in the tables come "
        "from another simulator and are labelled as such.", "",
        "## What was run", "",
        f"- scenarios: {', '.join(labels)}; generator size `{prof.get('generator_profile')}`; "
        f"seed {prof.get('seed')}; training: "
        + (f"recipe `{prof['recipe']}`, {json.dumps(prof.get('train', {}))}" if prof.get("recipe")
           else "not recorded in run.json (an interrupted bench of an older version, which recorded it only at the end)"),
        *(["- analytic model: " + ", ".join(f"{k} `{prof[k]}`" for k in ("robot", "params", "tool") if prof.get(k))]
          if any(prof.get(k) for k in ("robot", "params", "tool")) else []),
        f"- wall time of this invocation: {_minutes(meta.get('wall_seconds'))} min (datasets and trained "
        "models found in the caches are reused; each row's `train_seconds` is its own training time)"
        + _invocation_times(meta.get("invocations", [])),
        *_time_profile(meta.get("invocations", []), rows),
        (f"- machine: {machine['machine']}, {machine['processor']}, Python {machine['python']}; packages: "
         + ", ".join(f"{k} {v}" for k, v in machine["packages"].items())) if machine else
        f"- machine: not recorded in run.json ({no_machine})",
    ]
    for s, d in meta.get("datasets", {}).items():
        origin = f"config hash `{d['config_hash']}`" if d.get("config_hash") else "imported (no generator config)"
        lines.append(f"- data `{s}`: {origin}, data checksum `{str(d.get('checksum'))[:16]}`"
                     + (f", read from `{d.get('path')}`, robot `{d['robot']}`" if d.get("robot") else "")
                     + (f"; split {d['split']}" if d.get("split") else "")
                     + (f"; made or read in {_minutes(d['dataset_seconds'])} min of this invocation"
                        if d.get("dataset_seconds") is not None else ""))
        lines += [f"  - **import warning**: {w}" for w in d.get("import_warnings") or []]
    return lines


def _invocation_times(invocations: list) -> str:
    """The parts of a bench that took several invocations (resumed from its caches), and their sum. An
    invocation that began on empty caches starts the count: the ones before it worked on other caches."""
    cold = [k for k, i in enumerate(invocations) if i.get("cold_start")]
    if cold:
        invocations = invocations[cold[-1]:]
    if len(invocations) < 2:
        return "; it began on empty caches" if invocations and invocations[0].get("cold_start") else ""
    parts = [_minutes(i.get("wall_seconds")) + (" (not finished)" if "finished" in i and i["finished"] is None else "")
             for i in invocations]
    known = [float(i["wall_seconds"]) for i in invocations if i.get("wall_seconds") is not None]
    total = f"; in all {_minutes(sum(known))} min" if len(known) == len(invocations) else ""
    return "; all invocations [min]: " + ", ".join(parts) + total


def _time_profile(invocations: list, rows) -> list[str]:
    """Where the last invocation's time went: its wall and CPU seconds by phase (run.json), and the training
    and scoring CPU by family (results.csv's train_cpu_seconds, score_cpu_seconds: each row's own, in whichever
    invocation it ran)."""
    if not invocations or not invocations[-1].get("phases"):
        return []
    last = invocations[-1]
    cores = (f", {last['cpu_seconds'] / last['wall_seconds']:.2f} cores on average"
             if last.get("cpu_seconds") and last.get("wall_seconds") else "")
    phases = ", ".join(f"{k} {v['wall_seconds']:.0f} s wall / {v['cpu_seconds']:.0f} CPU-s"
                       for k, v in last["phases"].items())
    by_family: dict = {}
    for r in rows:
        f = by_family.setdefault(r.get("family") or "?", [0.0, 0.0])
        for i, key in enumerate(("train_cpu_seconds", "score_cpu_seconds")):
            f[i] += _finite_or_zero(r.get(key))
    families = ", ".join(f"{k} {v[0]:.0f} / {v[1]:.0f}" for k, v in sorted(by_family.items(), key=lambda kv: -kv[1][0]))
    return [f"- where this invocation's time went: {_minutes(last.get('wall_seconds'))} min wall, "
            f"{last.get('cpu_seconds', float('nan')):.0f} CPU-s{cores}; by phase: {phases} (the learned rows of every "
            "scenario train in one queue on the workers while this process fits the identified models and residual "
            "GPs and scores the rows that train nothing; the rest is reading data and drawing the report)",
            f"- CPU-s by family, training / scoring: {families}"]


def _finite_or_zero(value) -> float:
    """A results.csv number, or 0 where the row has none (an analytic row trains nothing)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return 0.0
    return x if math.isfinite(x) else 0.0


def _left_out_lines(meta: dict, notes_out: list[str], failed: list[dict]) -> list[str]:
    """The README's sections on what is not in the report: rows not run, figures not redrawn, failed rows."""
    lines = []
    skipped = meta.get("skipped") or []
    if skipped:
        lines += ["", "## Rows not run", "", "Each row the profile names that does not apply to a dataset, and why:", ""]
        lines += [f"- {k['scenario']}: " + (f"`{k['model']}` ({k['task'].replace('_', ' ')})" if k.get("model")
                                            else "the whole scenario") + f": {k['reason']}" for k in skipped]
    if notes_out:
        lines += ["", "## Not redrawn", ""] + [f"- {n}" for n in notes_out]
    if failed:
        lines += ["", "## Failed rows", ""] + [f"- {r['scenario']} {r['model']}: {r.get('error', '')}" for r in failed]
    return lines


def _files_lines(out_dir: Path, preds, reference_text, curve_figures: list[str], figures: list[str]) -> list[str]:
    """The README's "Files" section: what the report folder holds."""
    return ["", "## Files", "", "- `results.csv`: one row per (task, scenario, model), stable columns",
            *([f"- `{PREDICTIONS_FILE}` ({_megabytes(out_dir / PREDICTIONS_FILE)}): every row's test predictions "
               "and their targets (the figures are drawn from it; `hybrid-dyn report DIR` redraws the report from "
               "these files)"] if preds is not None else []),
            "- `tip_force.md`, `joint_torque.md` (+ `.tex`): tables in the seed's layout",
            *([f"- `{REFERENCE_COMPARISON_FILE}`: the seed's Tables 2 and 3 beside this report's"] if reference_text else []),
            *([f"- `{CURVES_FILE}`: each learned row's loss per epoch, how it stopped and the epoch kept "
               "(the learning-curve figures are drawn from it)"] if curve_figures else []),
            *[f"- `{f}`" for f in figures], ""]


def _minutes(seconds) -> str:
    return "-" if seconds is None else f"{float(seconds) / 60:.1f}"


def _megabytes(path: Path) -> str:
    return f"{path.stat().st_size / 1e6:.0f} MB" if path.exists() else "absent"


def rebuild_report(out_dir, log=print) -> list[str]:
    """``hybrid-dyn report DIR``: rewrite results.csv, the tables, the figures and README.md of a bench report
    folder from its files alone (results.csv, run.json, curves.json, predictions.h5): no training, no
    simulation, no dataset. Holds the folder's lock; refuses a folder that is not a bench report."""
    from ..outputs import output_lock
    from .integrity import read_checked_report
    from .results import results_columns, write_results

    out_dir = Path(out_dir)
    with output_lock(out_dir, "report folder"):
        # Everything is checked before anything is written: the marker, run.json's fields, and every row
        # against run.json's digest and predictions.h5 (integrity.read_checked_report, as compare reads).
        report = read_checked_report(out_dir)
        # Its own columns: a report written before a column was added is rewritten as it was.
        write_results(out_dir / "results.csv", report.rows, columns=results_columns(out_dir / "results.csv"))
        return write_report(out_dir, report.rows, report.meta, log=log)
