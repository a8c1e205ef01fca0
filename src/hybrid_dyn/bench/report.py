"""The benchmark report: tables laid out like the seed's, LaTeX, figures, README.

Everything here is drawn from the bench's files in the report folder, never from
a live run: results.csv (``results.py``), curves.json, run.json and predictions.h5
(``predictions.py``), so ``hybrid-dyn report DIR`` redraws the same report without
retraining or re-simulating. The headline findings are computed from those numbers,
never typed. The project's own acceptance floors are not here: they are a check
of their own (``checks/acceptance.py``), since they mean nothing on a user's data.
"""
from __future__ import annotations

import json
import platform
from pathlib import Path

import numpy as np

from ..data import package_versions
from .catalog import reference_label
from .predictions import PREDICTIONS_FILE, Predictions, PredictionsError
from .hybrids import hybrid_lines
from .results import CURVES_FILE, read_curves
from .seed_comparison import SEED_COMPARISON_FILE, seed_comparison_text
from .seed_reference import GAZ2019_VALIDATION_RMSE, SEED_TABLE1, SEED_TABLE2, SEED_TABLE3, seed_dataset_label


def _f(x, nd=4) -> str:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return "-"
    return "-" if not np.isfinite(x) else f"{x:.{nd}f}"


def _ok(rows):
    return [r for r in rows if r.get("status") == "ok"]


# Reference rows show the cost of a choice (a seed net on the raw, untared base sensor: its per-run
# bias cannot be learned from a window), not a contender: labelled in the tables, never a family's best.
# Which rows they are, and their labels, is declared with the row (``rows.Row.reference``).
def _contenders(rows):
    """The scored rows that may be a family's best: every ok row but the reference rows."""
    return [r for r in _ok(rows) if reference_label(r["model"]) is None]


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
    esc = lambda s: (str(s).replace("_", r"\_").replace("%", r"\%").replace("#", r"\#").replace("&", r"\&")
                     .replace(CAP_MARK, r"$^\dagger$"))
    cols = "l" * 2 + "r" * (len(header) - 2)
    out = [r"\begin{table}[ht]", r"\centering", rf"\caption{{{esc(caption)}}}", rf"\begin{{tabular}}{{{cols}}}",
           r"\hline", " & ".join(esc(h) for h in header) + r" \\", r"\hline"]
    out += [" & ".join(esc(c) for c in row) + r" \\" for row in body]
    out += [r"\hline", r"\end{tabular}", r"\end{table}"]
    return "\n".join(out) + "\n"


TIP_HEADER = ["model", "family", "inputs", "val loss", "test loss", "RMSE [N]", "RMSE / noise", "RMSE x/y/z [N]",
              "contact", "free", "max err", "train s", "us/sample", "us/call", "params", "epochs (stop)",
              "seed val loss*", "seed test loss*", "seed RMSE* [N]"]
TAU_HEADER = ["model", "family", "inputs", "val loss", "test loss", "RMSE [Nm]", "RMSE per joint [Nm]",
              "contact", "free", "max err", "train s", "us/sample", "us/call", "params", "epochs (stop)",
              "seed val loss*", "seed test loss*", "seed RMSE* [Nm]"]
N_SEED_COLUMNS = 3  # the headers' last columns: the seed's published figures
CAP_MARK = "†"  # a learned row stopped by the epoch cap while still improving (footnoted in each table)
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
    return f"{r['model']} ({label})" if label else r["model"]


def _row_cells(r, task, scenario):
    n = 3 if task == "tip_force" else 7
    per = "/".join(_f(r.get(f"rmse_{j + 1}"), 3) for j in range(n))
    if task == "tip_force":
        seed = SEED_TABLE2.get(r["model"])
    else:
        seed = SEED_TABLE3.get((r["model"], seed_dataset_label(scenario)))
    header = TIP_HEADER if task == "tip_force" else TAU_HEADER
    if r.get("status") != "ok":
        return [_model_cell(r), r.get("family", ""), r.get("inputs", ""), "FAILED: " + str(r.get("error", ""))[:80]] + \
            ["-"] * (len(header) - 4)
    # Tip force: the RMSE as a multiple of the base sensor's per-axis noise RMS (the limit of a base-sensor method).
    over_noise = [_f(_ratio(r.get("rmse"), r.get("noise_rms")), 2)] if task == "tip_force" else []
    return [_model_cell(r), r["family"], r.get("inputs", ""), _f(r["val_loss"]), _f(r["test_loss"]), _f(r["rmse"]),
            *over_noise, per,
            _f(r.get("rmse_contact")), _f(r.get("rmse_free")), _f(r.get("max_error"), 2), _f(r.get("train_seconds"), 1),
            _f(r.get("infer_us_per_sample"), 2), _f(r.get("infer_us_per_call"), 1), r.get("n_params", "") or "0",
            _stop_cell(r), *(_f(s) for s in (seed or ("", "", "")))]


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
    seed_tab = "Table 2" if task == "tip_force" else "Table 3"
    md = [f"# {title}", "",
          f"Laid out like the seed's {seed_tab}. Losses: MSE on targets standardised with the train split's "
          f"statistics (the seed's losses also hold a regularisation term). RMSE over all test samples and "
          f"components [{unit}], then per component; 'contact' / 'free': samples with |F_tip| above / below 1 N.",
          "", f"\\* Columns marked * are the seed's published figures (Kruzic et al. 2021, {seed_tab}): "
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
        caption = f"{title}, {scenario}"
        if capped:
            md += [CAP_FOOTNOTE.replace("<scenario>", scenario) + f" Here: {', '.join(f'`{m}`' for m in capped)}.", ""]
            caption += f"; {CAP_MARK} stopped by the epoch cap while still improving: may not have converged"
        keep = 6  # model, family, inputs, losses, RMSE; then epochs (stop) and the seed's figures
        tail = N_SEED_COLUMNS + (1 if with_stop else 0)
        tex.append(_latex(header[:keep] + header[-tail:], [b[:keep] + b[-tail:] for b in body], caption))
    if task == "tip_force":
        md += ["Seed Table 1 architectures: " + "; ".join(f"`{k}` {v}" for k, v in SEED_TABLE1.items()), ""]
    else:
        md += ["Gaz et al. 2019 identified model on the real Panda (another setting, not measured here), "
               "validation torque RMSE per joint [Nm]: " + ", ".join(f"{v:.2f}" for v in GAZ2019_VALIDATION_RMSE), ""]
    return "\n".join(md), "\n".join(tex)


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
    if lines:
        # Beside physics a net's RMSE can read as "learning is broken"; the nMSE says how much it learned.
        lines.append("- nMSE: the test MSE over the test target's variance, per axis or joint, then averaged: "
                     "1 is what predicting the mean gives, 0 is exact. Every joint weighs the same, so a wrist joint "
                     "with little torque variance counts as much as the shoulder, and nMSE can rank rows "
                     "differently from RMSE.")
    return lines


# -------------------------------------------------------------------- figures
def _save(fig, out_dir: Path, name: str, dpi: int) -> str:
    """Lay out, write ``out_dir/name`` and close ``fig``; returns the file's name for the README."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(out_dir / name, dpi=dpi)
    plt.close(fig)
    return name


def _figures(out_dir: Path, rows, preds: Predictions | None, seed: int = 0) -> list[str]:
    """The RMSE bars (from the rows) and, where ``preds`` (predictions.h5) holds them, the traces and the
    error-vs-force figures; ``seed`` picks the traced test instance (the profile's seed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    made = []
    ok = _contenders(rows)  # the figures compare families' best rows: reference rows are in the tables
    # RMSE bars: best model per family, per scenario and task.
    for task, unit in (("tip_force", "N"), ("joint_torque", "Nm")):
        scen = list(dict.fromkeys(r["scenario"] for r in ok if r["task"] == task))
        if not scen:
            continue
        fig, axes = plt.subplots(1, len(scen), figsize=(4.5 * len(scen), 3.6), squeeze=False)
        for ax, s in zip(axes[0], scen):
            fams = {}
            for r in ok:
                if r["task"] == task and r["scenario"] == s:
                    if r["family"] not in fams or float(r["rmse"]) < float(fams[r["family"]]["rmse"]):
                        fams[r["family"]] = r
            items = sorted(fams.items(), key=lambda kv: float(kv[1]["rmse"]))
            ax.bar([f"{k}\n{v['model']}" for k, v in items], [float(v["rmse"]) for _, v in items], color="tab:blue")
            ax.set_title(s)
            ax.set_ylabel(f"test RMSE [{unit}]")
            ax.tick_params(axis="x", labelsize=7, rotation=30)
        made.append(_save(fig, out_dir, f"rmse_by_family_{task}.png", dpi=110))

    for scenario in (preds.scenarios() if preds is not None else []):
        test = preds.test(scenario)
        if not test:
            continue
        k = int(np.random.default_rng(seed).integers(len(test)))
        inst = test[k]
        for task, target, unit in (("tip_force", "tip_force", "N"), ("joint_torque", "tau_m", "Nm")):
            models = [r for r in ok if r["task"] == task and r["scenario"] == scenario]
            if not models or target not in inst:
                continue
            picks = {}
            for fam in ("analytic", "seed-net", "residual", "delan", "identified"):
                b = _best(models, task, scenario, lambda r, fam=fam: r["family"] == fam)
                if b:
                    picks[b["model"]] = preds.get(scenario, task, b["model"])
            y = inst[target]
            t = inst["t"] - inst["t"][0]
            n = y.shape[1]
            fig, axes = plt.subplots(n, 1, figsize=(9, 1.6 * n + 0.6), sharex=True, squeeze=False)
            for j in range(n):
                ax = axes[j, 0]
                ax.plot(t, y[:, j], "k-", lw=1.2, label="measured")
                for name, row_preds in picks.items():
                    if row_preds is not None:
                        ax.plot(t, row_preds[k][:, j], lw=0.9, label=name)
                ax.set_ylabel(f"{'xyz'[j] if n == 3 else f'joint {j + 1}'} [{unit}]", fontsize=8)
            axes[0, 0].legend(fontsize=7, ncol=3, loc="upper right")
            axes[-1, 0].set_xlabel("t [s]")
            fig.suptitle(f"{scenario}, test instance {inst['name']}: {task.replace('_', ' ')}", fontsize=10)
            made.append(_save(fig, out_dir, f"traces_{task}_{scenario}.png", dpi=100))
        # Error vs contact force magnitude, tip force (where tip-force rows ran).
        if any(r["task"] == "tip_force" and r["scenario"] == scenario for r in ok) and "tip_force" in inst:
            f_true = np.concatenate([i.get("tip_force_truth", i["tip_force"]) for i in test])
            mag = np.linalg.norm(f_true, axis=1)
            bins = np.array([0, 1, 5, 10, 15, 20, np.inf])
            which = np.digitize(mag, bins) - 1
            fig, ax = plt.subplots(figsize=(6.5, 3.8))
            for fam in ("analytic", "seed-net", "residual"):
                b = _best(ok, "tip_force", scenario, lambda r, fam=fam: r["family"] == fam)
                fam_preds = preds.get(scenario, "tip_force", b["model"]) if b else None
                if fam_preds is None:
                    continue
                err = np.linalg.norm(np.concatenate(fam_preds) - np.concatenate([i["tip_force"] for i in test]), axis=1)
                vals = [np.sqrt(np.mean(err[which == i] ** 2)) if (which == i).any() else np.nan for i in range(len(bins) - 1)]
                ax.plot(range(len(vals)), vals, "o-", label=f"{fam}: {b['model']}")
            ax.set_xticks(range(len(bins) - 1), ["0-1", "1-5", "5-10", "10-15", "15-20", ">20"])
            ax.set_xlabel("|F_tip| true [N]")
            ax.set_ylabel("RMS of |error| [N]")
            ax.set_title(f"{scenario}: tip-force error vs contact force")
            ax.legend(fontsize=8)
            made.append(_save(fig, out_dir, f"error_vs_force_{scenario}.png", dpi=110))
    return made


def learning_curve_figures(out_dir: Path, curves: dict) -> list[str]:
    """``learning_curves_<scenario>.png``: one panel per learned row, train and validation loss per epoch.

    ``curves`` is curves.json (``runner.write_curves``): scenario -> model -> {task, epochs, stopped_by,
    best_epoch, history, initial_val_loss}. Losses are standardized MSE on a log axis; the star marks the
    epoch whose weights were kept, the dotted line the untrained model's validation loss, and a title in
    red a row stopped by the epoch cap (it may not have converged). The learning rate, where the history
    has it, is the grey line on the right axis.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    made = []
    for scenario, models in curves.items():
        if not models:
            continue
        ncols = min(4, len(models))
        nrows = -(-len(models) // ncols)
        fig, axes = plt.subplots(nrows, ncols, figsize=(3.3 * ncols, 2.5 * nrows + 0.5), squeeze=False)
        for ax in axes.flat[len(models):]:
            ax.set_visible(False)
        for ax, (model, c) in zip(axes.flat, models.items()):
            hist = c.get("history") or []
            epochs = np.arange(len(hist))
            train = np.array([float(h["train_loss"]) for h in hist])
            val = np.array([float(h["val_loss"]) for h in hist])
            ax.semilogy(epochs, train, "-", color="tab:blue", lw=1.0, label="train")
            ax.semilogy(epochs, val, "-", color="tab:orange", lw=1.2, label="validation")
            initial = c.get("initial_val_loss")
            if initial is not None and np.isfinite(float(initial)) and float(initial) > 0:
                ax.axhline(float(initial), color="0.5", ls=":", lw=0.9, label="untrained (val)")
            best = int(c.get("best_epoch", -1))
            if 0 <= best < len(hist):
                ax.plot([best], [val[best]], "*", color="tab:red", ms=9, label=f"kept: epoch {best}")
            elif hist:
                ax.text(0.03, 0.05, "no epoch beat the untrained model: it was kept", transform=ax.transAxes, fontsize=6)
            lr = [h.get("lr") for h in hist]
            if hist and all(v is not None for v in lr):
                ax2 = ax.twinx()
                ax2.semilogy(epochs, lr, "--", color="0.6", lw=0.7, drawstyle="steps-post", label="lr")
                ax2.tick_params(labelsize=6, colors="0.4")
                ax2.set_ylabel("lr", fontsize=6, color="0.4")
            if not hist:
                ax.text(0.5, 0.5, "no epoch trained", transform=ax.transAxes, ha="center", fontsize=8)
            capped = c.get("stopped_by") == "epoch-cap"
            label = reference_label(model)
            ax.set_title(f"{model}{' (reference)' if label else ''}\n{c.get('epochs', len(hist))} epochs, "
                         f"{c.get('stopped_by', '?')}{' ' + CAP_MARK if capped else ''}",
                         fontsize=8, color="tab:red" if capped else "black")
            ax.set_xlabel("epoch", fontsize=7)
            ax.set_ylabel(f"{str(c.get('task', '')).replace('_', ' ')} loss", fontsize=7)
            ax.tick_params(labelsize=6)
            ax.legend(fontsize=5.5, loc="best")
        fig.suptitle(f"{scenario}: learning curves (standardized MSE; star: the epoch kept)", fontsize=10)
        made.append(_save(fig, out_dir, f"learning_curves_{scenario}.png", dpi=100))
    return made


def convergence_lines(rows, curve_figures: list[str]) -> list[str]:
    """The README's convergence section: how each learned row stopped, the capped rows named."""
    learned = [r for r in _ok(rows) if r.get("stopped_by") not in (None, "")]
    if not learned:
        return []
    counts = {}
    for r in learned:
        counts[r["stopped_by"]] = counts.get(r["stopped_by"], 0) + 1
    lines = ["", "## Convergence of the learned rows", "",
             f"- stopped by: {', '.join(f'{k} {v}' for k, v in sorted(counts.items()))} (of {len(learned)} learned rows); "
             "the `epochs (stop)` column of each table and `epochs`, `stopped_by`, `best_epoch` in results.csv"]
    if curve_figures:
        lines.append("- learning curves, train and validation loss per epoch with the kept epoch marked (from "
                     "`curves.json`): " + ", ".join(f"`{f}`" for f in curve_figures))
    capped = [r for r in learned if _is_capped(r)]
    if capped:
        lines.append(f"- {CAP_MARK} stopped by the epoch cap while still improving, so they may not have converged: "
                     + ", ".join(f"{r['scenario']} `{r['model']}` ({r.get('epochs')} epochs)" for r in capped))
    refs = sorted({r["model"] for r in learned if reference_label(r["model"])})
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
    from .profiles import is_dataset_path

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
    out_dir = Path(out_dir)
    for task in ("tip_force", "joint_torque"):
        md, tex = task_tables(rows, task)
        (out_dir / f"{task}.md").write_text(md)
        (out_dir / f"{task}.tex").write_text(tex)
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
    _remove_stale_figures(out_dir, figures)
    failed = [r for r in rows if r.get("status") != "ok"]
    machine = meta.get("machine")
    labels = meta.get("scenarios") or {s: s for s in prof.get("scenarios", [])}
    command = _command(prof)
    lines = [
        f"# Benchmark report: profile `{prof.get('name', '?')}`", "",
        f"Produced by `{command}`; every number below and in the "
        "tables was computed by that command on this data (`hybrid-dyn report` redraws it only after checking "
        "every row against the digest the bench recorded in run.json and the stored predictions). Seed (Kruzic et al. 2021) figures in the tables come "
        "from another simulator and are labelled as such.", "",
        "## What was run", "",
        f"- scenarios: {', '.join(labels)}; generator profile `{prof.get('generator_profile')}`; "
        f"seed {prof.get('seed')}; training: "
        + (f"recipe `{prof['recipe']}`, {json.dumps(prof.get('train', {}))}" if prof.get("recipe")
           else "not recorded in run.json (an interrupted bench of an older version, which recorded it only at the end)"),
        *([f"- analytic model: " + ", ".join(f"{k} `{prof[k]}`" for k in ("robot", "params", "tool") if prof.get(k))]
          if any(prof.get(k) for k in ("robot", "params", "tool")) else []),
        f"- wall time of this invocation: {_minutes(meta.get('wall_seconds'))} min (datasets and trained "
        "models found in the caches are reused; each row's `train_seconds` is its own training time)"
        + ("; all invocations [min]: " + ", ".join(_minutes(i.get("wall_seconds"))
                                                 for i in meta.get("invocations", [])) if len(meta.get("invocations", [])) > 1 else ""),
        (f"- machine: {machine['machine']}, {machine['processor']}, Python {machine['python']}; packages: "
         + ", ".join(f"{k} {v}" for k, v in machine["packages"].items())) if machine else
        "- machine: not recorded in run.json (a report written before it was)",
    ]
    for s, d in meta.get("datasets", {}).items():
        origin = f"config hash `{d['config_hash']}`" if d.get("config_hash") else "imported (no generator config)"
        lines.append(f"- data `{s}`: {origin}, data checksum `{str(d.get('checksum'))[:16]}`"
                     + (f", read from `{d.get('path')}`, robot `{d['robot']}`" if d.get("robot") else "")
                     + (f"; split {d['split']}" if d.get("split") else "")
                     + (f"; made or read in {_minutes(d['dataset_seconds'])} min of this invocation"
                        if d.get("dataset_seconds") is not None else ""))
        lines += [f"  - **import warning**: {w}" for w in d.get("import_warnings") or []]
    notes = prof.get("notes") or []
    if notes:
        lines += ["", "## Method notes", ""] + [f"- {n}" for n in notes]
    lines += ["", "## Headline findings", ""] + findings(rows)
    if any(_is_capped(r) for r in _contenders(rows)):
        lines += ["", f"{CAP_MARK}: stopped by the epoch cap while still improving; it may not have converged "
                      "(see the learning curves)."]
    lines += hybrid_lines(rows)
    lines += convergence_lines(rows, curve_figures)
    seed_text = seed_comparison_text(rows, read_curves(out_dir / CURVES_FILE))
    if seed_text is not None:  # the seed's nets are in this report: its tables beside ours
        (out_dir / SEED_COMPARISON_FILE).write_text(seed_text)
        lines += ["", "## The seed's tables", "", f"`{SEED_COMPARISON_FILE}`: the seed's Tables 2 and 3 (Kruzic "
                  "et al. 2021, another simulator) row by row beside this report's seed nets, the architecture "
                  "ordering in both, and each net's training and validation loss at the kept round."]
    skipped = meta.get("skipped") or []
    if skipped:
        lines += ["", "## Rows not run", "", "Each row the profile names that does not apply to a dataset, and why:", ""]
        lines += [f"- {k['scenario']}: " + (f"`{k['model']}` ({k['task'].replace('_', ' ')})" if k.get("model")
                                            else "the whole scenario") + f": {k['reason']}" for k in skipped]
    if notes_out:
        lines += ["", "## Not redrawn", ""] + [f"- {n}" for n in notes_out]
    if failed:
        lines += ["", "## Failed rows", ""] + [f"- {r['scenario']} {r['model']}: {r.get('error', '')}" for r in failed]
    lines += ["", "## Files", "", "- `results.csv`: one row per (task, scenario, model), stable columns",
              *([f"- `{PREDICTIONS_FILE}` ({_megabytes(out_dir / PREDICTIONS_FILE)}): every row's test predictions "
                 "and their targets (the figures are drawn from it; `hybrid-dyn report DIR` redraws the report from "
                 "these files)"] if preds is not None else []),
              "- `tip_force.md`, `joint_torque.md` (+ `.tex`): tables in the seed's layout",
              *([f"- `{SEED_COMPARISON_FILE}`: the seed's Tables 2 and 3 beside this report's"] if seed_text else []),
              *([f"- `{CURVES_FILE}`: each learned row's loss per epoch, how it stopped and the epoch kept "
                 "(the learning-curve figures are drawn from it)"] if curve_figures else []),
              *[f"- `{f}`" for f in figures], ""]
    (out_dir / "README.md").write_text("\n".join(lines))
    for note in notes_out:
        log(f"[report] {note}")
    return notes_out


def _minutes(seconds) -> str:
    return "-" if seconds is None else f"{float(seconds) / 60:.1f}"


# The figures a report draws (``_figures``, ``learning_curve_figures``): one of these left from an earlier
# report in the same folder (another dataset, another scenario) is removed, not shown beside the new ones.
FIGURE_PREFIXES = ("rmse_by_family_", "traces_", "error_vs_force_", "learning_curves_")


def _remove_stale_figures(out_dir: Path, figures: list[str]) -> None:
    for p in out_dir.glob("*.png"):
        if p.name.startswith(FIGURE_PREFIXES) and p.name not in figures and p.is_file():
            p.unlink()


def _megabytes(path: Path) -> str:
    return f"{path.stat().st_size / 1e6:.0f} MB" if path.exists() else "absent"


def rebuild_report(out_dir, log=print) -> list[str]:
    """``hybrid-dyn report DIR``: rewrite results.csv, the tables, the figures and README.md of a bench report
    folder from its files alone (results.csv, run.json, curves.json, predictions.h5): no training, no
    simulation, no dataset. Holds the folder's lock; refuses a folder that is not a bench report."""
    from ..errors import OutputPathError
    from ..outputs import output_lock
    from .integrity import check_meta, read_run_json, verify_results
    from .results import read_results, results_columns, write_results

    out_dir = Path(out_dir)
    marker = out_dir / "run.json"
    if not marker.is_file() or not (out_dir / "results.csv").is_file():
        raise OutputPathError(f"{out_dir} is not a bench report folder: it needs run.json and results.csv "
                              "(written by hybrid-dyn bench)")
    with output_lock(out_dir, "report folder"):
        # Everything is checked before anything is written: the marker, run.json's fields, and every row
        # against run.json's digest and predictions.h5 (integrity.py).
        meta = read_run_json(out_dir)
        check_meta(meta, marker)
        rows = read_results(out_dir / "results.csv")
        try:
            preds = Predictions(out_dir / PREDICTIONS_FILE)
        except PredictionsError:  # absent or unreadable: the digest alone vouches for the rows (write_report notes it)
            preds = None
        verify_results(rows, meta, preds, out_dir)
        # Its own columns: a report written before a column was added is rewritten as it was.
        write_results(out_dir / "results.csv", rows, columns=results_columns(out_dir / "results.csv"))
        return write_report(out_dir, rows, meta, log=log)
