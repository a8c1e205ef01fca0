"""The report's tables: one per task, laid out like the reference study's (Kruzic et al. 2021) Tables 2
and 3, in Markdown and LaTeX, and the choice of the rows a report compares (every scored row but the reference rows).

Apart from the README (``report.py``) and the figures (``report_figures.py``) because a table is
drawn from results.csv alone, cell by cell, and the acceptance check (``checks/acceptance.py``) and
``compare.py`` pick rows the same way the tables and figures do.
"""
from __future__ import annotations

import numpy as np

from .catalog import reference_label
from .metrics import ANSWERED_FLOOR
from .results import SCORED_STATUSES
from .row_checks import IMPLAUSIBLE, row_notes
from .reference_study import (GAZ2019_VALIDATION_RMSE, REFERENCE_TABLE1, REFERENCE_TABLE2, REFERENCE_TABLE3,
                              reference_dataset_label)


def _f(x, nd=4) -> str:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return "-"
    return "-" if not np.isfinite(x) else f"{x:.{nd}f}"


def _ok(rows):
    return [r for r in rows if r.get("status") == "ok"]


# Reference rows show the cost of a choice (a seed-net row on the raw, untared base sensor: its per-run
# bias cannot be learned from a window), not a contender: labelled in the tables, never a family's best.
# Which rows they are, and their labels, is declared with the row (``rows.Row.reference``).
def _contenders(rows):
    """The scored rows that may be a family's best: every ok row but the reference rows and the rows that
    answered under ANSWERED_FLOOR of the test samples (``low_answer``)."""
    return [r for r in _ok(rows) if reference_label(r["model"]) is None and not low_answer(r)]


def answered_share(r) -> float:
    """The row's answered share of the test samples (results.csv ``answered_share``); 1 for a report written
    before the column (every row then answered every sample: refusals were scored as zero forces)."""
    v = r.get("answered_share")
    try:
        return 1.0 if v in (None, "") else float(v)
    except (TypeError, ValueError):
        return float("nan")


def low_answer(r) -> bool:
    """Whether a scored row answered under ANSWERED_FLOOR of the test samples (marked, never a family's best)."""
    return r.get("status") in SCORED_STATUSES and not answered_share(r) >= ANSWERED_FLOOR


def _best(rows, task, scenario, pred) -> dict | None:
    cand = [r for r in _contenders(rows) if r["task"] == task and r["scenario"] == scenario and pred(r)]
    return min(cand, key=lambda r: float(r["rmse"])) if cand else None


best_row = _best  # public: (rows, task, scenario, pred) -> the least-RMSE contender, or None


# --------------------------------------------------------------------- tables
def _table(header: list, body: list) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in body]
    return "\n".join(lines)


def _latex(header: list, body: list, caption: str) -> str:
    def esc(s):
        return (str(s).replace("_", r"\_").replace("%", r"\%").replace("#", r"\#").replace("&", r"\&")
                .replace(CAP_MARK, r"$^\dagger$").replace(IMPLAUSIBLE_MARK, r"$^\ddagger$")
                .replace(LOW_ANSWER_MARK, r"\S{}"))

    cols = "l" * 2 + "r" * (len(header) - 2)
    out = [r"\begin{table}[ht]", r"\centering", rf"\caption{{{esc(caption)}}}", rf"\begin{{tabular}}{{{cols}}}",
           r"\hline", " & ".join(esc(h) for h in header) + r" \\", r"\hline"]
    out += [" & ".join(esc(c) for c in row) + r" \\" for row in body]
    out += [r"\hline", r"\end{tabular}", r"\end{table}"]
    return "\n".join(out) + "\n"


TIP_HEADER = ["model", "family", "inputs", "val loss", "test loss", "RMSE [N]", "answered", "RMSE / noise", "RMSE x/y/z [N]",
              "contact", "free", "max err", "train s", "us/sample", "us/call", "params", "epochs (stop)",
              "seed val loss*", "seed test loss*", "seed RMSE* [N]"]
TAU_HEADER = ["model", "family", "inputs", "val loss", "test loss", "RMSE [Nm]", "answered", "RMSE per joint [Nm]",
              "contact", "free", "max err", "train s", "us/sample", "us/call", "params", "epochs (stop)",
              "seed val loss*", "seed test loss*", "seed RMSE* [Nm]"]
N_REFERENCE_COLUMNS = 3  # the headers' last columns: the reference study's published figures
CAP_MARK = "†"  # a learned row stopped by the epoch cap while still improving (footnoted in each table)
IMPLAUSIBLE_MARK = "‡"  # an identified row whose parameters are outside the robot's bounds (row_checks.py)
LOW_ANSWER_MARK = "§"  # a row that answered under ANSWERED_FLOOR of the test samples (metrics.py)
ANSWERED_NOTE = (f"'answered': the share of the test samples a row answered; a refusal (an estimator declining to "
                 f"answer, e.g. before its start-up check passed) is not an error, so every error figure is over the "
                 f"answered samples. {LOW_ANSWER_MARK}: answered under {ANSWERED_FLOOR:.0%}: never a family's best.")
CAP_FOOTNOTE = (f"{CAP_MARK} Stopped by the epoch cap (`max_epochs`) while its validation loss was still improving: "
                "this row may not have converged, so its error may overstate what the model can do. Its train and "
                "validation loss per epoch are in `learning_curves_<scenario>.png`.")
STOP_NOTE = ("'epochs (stop)': the epochs a learned row trained and why it stopped: `patience` (no validation "
             "improvement for `patience` epochs), `lr-floor` (the learning rate reached its floor and plateaued "
             f"there), `epoch-cap` ({CAP_MARK}) or `budget` (the budgeted recipe spent its fixed number of optimizer steps: "
             "its 'epochs' are then validation rounds, each a fixed share of the budget); it keeps the weights of its best validation epoch (`best_epoch` "
             "in results.csv, 0-based; 'untrained kept': no epoch beat the untrained model, e.g. a residual that "
             "never beat its physics part). The learning curves are in `learning_curves_<scenario>.png`.")


def _is_capped(r) -> bool:
    return r.get("stopped_by") == "epoch-cap"


def _cap_mark(r) -> str:
    return f" {CAP_MARK}" if _is_capped(r) else ""


def _stop_cell(r) -> str:
    """'12 (patience)', '30 (epoch-cap) †'; '-' for a row that did not train (analytic, identified)."""
    if r.get("stopped_by") in (None, ""):
        return "-"
    kept = "; untrained kept" if str(r.get("best_epoch")) == "-1" else ""
    return f"{r.get('epochs', '?')} ({r['stopped_by']}{kept}){_cap_mark(r)}"


def _model_cell(r) -> str:
    label = reference_label(r["model"])
    return (f"{r['model']} ({label})" if label else r["model"]) + implausible_mark(r) \
        + (f" {LOW_ANSWER_MARK}" if low_answer(r) else "")


def _answered_cell(r) -> str:
    share = answered_share(r)
    return "-" if share != share else f"{100 * share:.1f} %"


def implausible_mark(r) -> str:
    return f" {IMPLAUSIBLE_MARK}" if r.get("status") == IMPLAUSIBLE else ""


def notes_by_text(rows) -> dict:
    """Each distinct note of ``rows`` (results.csv ``notes``, in first-seen order) -> the rows it applies to."""
    out: dict = {}
    for r in rows:
        for n in row_notes(r):
            out.setdefault(n, []).append(r)
    return out


def notes_lines(rows) -> list[str]:
    """The notes under a table: each note once, with the rows it applies to (``row_checks.py``)."""
    notes = notes_by_text(rows)
    if not notes:
        return []
    lines = [f"Notes (what these numbers cannot show; results.csv `notes`). {IMPLAUSIBLE_MARK}: parameters outside "
             "the robot's bounds (status `implausible`): scored, never a family's best.", ""]
    lines += [f"- {n} — " + ", ".join(f"`{r['model']}`{implausible_mark(r)}" for r in rs) for n, rs in notes.items()]
    return lines + [""]


def _row_cells(r, task, scenario):
    n = 3 if task == "tip_force" else 7
    per = "/".join(_f(r.get(f"rmse_{j + 1}"), 3) for j in range(n))
    if task == "tip_force":
        published = REFERENCE_TABLE2.get(r["model"])
    else:
        published = REFERENCE_TABLE3.get((r["model"], reference_dataset_label(scenario)))
    header = TIP_HEADER if task == "tip_force" else TAU_HEADER
    if r.get("status") not in SCORED_STATUSES:
        return [_model_cell(r), r.get("family", ""), r.get("inputs", ""), "FAILED: " + str(r.get("error", ""))[:80]] + \
            ["-"] * (len(header) - 4)
    # Tip force: the RMSE as a multiple of the base sensor's per-axis noise RMS (the limit of a base-sensor method).
    over_noise = [_f(_ratio(r.get("rmse"), r.get("noise_rms")), 2)] if task == "tip_force" else []
    return [_model_cell(r), r["family"], r.get("inputs", ""), _f(r["val_loss"]), _f(r["test_loss"]), _f(r["rmse"]),
            _answered_cell(r), *over_noise, per,
            _f(r.get("rmse_contact")), _f(r.get("rmse_free")), _f(r.get("max_error"), 2), _f(r.get("train_seconds"), 1),
            _f(r.get("infer_us_per_sample"), 2), _f(r.get("infer_us_per_call"), 1), r.get("n_params", "") or "0",
            _stop_cell(r), *(_f(s) for s in (published or ("", "", "")))]


def refusal_lines(rows, unit: str) -> list[str]:
    """Under a table: the rows that refused samples, with the refused-as-zero RMSE (each refusal scored as a
    zero prediction, the figure the bench gave before refusals were told apart) beside their own."""
    refusing = [r for r in rows if r.get("status") in SCORED_STATUSES and answered_share(r) < 1.0]
    if not refusing:
        return []
    return [ANSWERED_NOTE + f" Rows that refused samples (RMSE over the answered ones; with every refusal scored "
            f"as a zero, results.csv `rmse_refused_as_zero`) [{unit}]: "
            + "; ".join(f"`{r['model']}` {_answered_cell(r)} answered, {_f(r['rmse'])} (as zero: "
                        f"{_f(r.get('rmse_refused_as_zero'))})" for r in refusing) + ".", ""]


def _ratio(a, b) -> float:
    try:
        return float(a) / float(b)
    except (TypeError, ValueError, ZeroDivisionError):
        return float("nan")


def task_tables(rows, task: str) -> tuple[str, str]:
    """(markdown, latex) for one task over every scenario. The 'epochs (stop)' column is shown where
    results.csv records how rows stopped (a report written before it did is redrawn as it was)."""
    header = TIP_HEADER if task == "tip_force" else TAU_HEADER
    with_stop = any("stopped_by" in r for r in rows)
    stop_col = header.index("epochs (stop)")
    if not with_stop:
        header = header[:stop_col] + header[stop_col + 1:]
    unit = "N" if task == "tip_force" else "Nm"
    title = "Tip-force estimation" if task == "tip_force" else "Joint-torque estimation"
    reference_table = "Table 2" if task == "tip_force" else "Table 3"
    md = [f"# {title}", "",
          f"Laid out like the seed's {reference_table}. Losses: MSE on targets standardised with the train split's "
          f"statistics (the seed's losses also hold a regularisation term). RMSE over all test samples and "
          f"components [{unit}], then per component; 'contact' / 'free': samples with |F_tip| above / below 1 N.",
          "", f"\\* Columns marked * are the seed's published figures (Kruzic et al. 2021, {reference_table}): "
          "**figures from another simulator** (CoppeliaSim, 50 ms steps) and another data set, shown for "
          "orientation only, not measured here. Beside the `real-*` scenarios they are the seed's *real Panda* "
          "rows: **another robot** (the toolkit's real logs are of a KUKA LWR, a Baxter and a SARCOS arm).", "",
          *([STOP_NOTE, ""] if with_stop else [])]
    tex = []
    for scenario in dict.fromkeys(r["scenario"] for r in rows):
        here = [r for r in rows if r["task"] == task and r["scenario"] == scenario]
        body = [_row_cells(r, task, scenario) for r in here]
        if not with_stop:
            body = [b[:stop_col] + b[stop_col + 1:] for b in body]
        if not body:
            continue
        capped = [r["model"] for r in _ok(here) if _is_capped(r)]
        md += [f"## {scenario}", ""]
        noise = [float(r["noise_rms"]) for r in rows if r["task"] == task and r["scenario"] == scenario
                 and r.get("status") == "ok" and r.get("noise_rms") not in (None, "")]
        if task == "tip_force" and noise and np.isfinite(noise[0]):
            md += [f"Base sensor noise RMS per force axis: {noise[0]:.4f} N (recorded minus noise-free force on the "
                   "test split, each run's bias removed); 'RMSE / noise' is each row's RMSE in that unit.", ""]
        md += [_table(header, body), ""]
        md += refusal_lines(here, unit)
        md += notes_lines(here)
        caption = f"{title}, {scenario}"
        if capped:
            md += [CAP_FOOTNOTE.replace("<scenario>", scenario) + f" Here: {', '.join(f'`{m}`' for m in capped)}.", ""]
            caption += f"; {CAP_MARK} stopped by the epoch cap while still improving: may not have converged"
        keep = 7  # model, family, inputs, losses, RMSE, answered; then epochs (stop) and the reference study's figures
        tail = N_REFERENCE_COLUMNS + (1 if with_stop else 0)
        tex.append(_latex(header[:keep] + header[-tail:], [b[:keep] + b[-tail:] for b in body], caption))
    if task == "tip_force":
        md += ["Seed Table 1 architectures: " + "; ".join(f"`{k}` {v}" for k, v in REFERENCE_TABLE1.items()), ""]
    else:
        md += ["Gaz et al. 2019 identified model on the real Panda (another setting, not measured here), "
               "validation torque RMSE per joint [Nm]: " + ", ".join(f"{v:.2f}" for v in GAZ2019_VALIDATION_RMSE), ""]
    return "\n".join(md), "\n".join(tex)
