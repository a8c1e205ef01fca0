"""The report's figures: the RMSE bars per family, the traces and the error-vs-force figures (from
predictions.h5) and the learning curves (from curves.json). A figure an earlier report left in the
folder is removed by ``report.write_report``, by run.json's record of what it wrote (never by its name).

Apart from the README (``report.py``) because the figures are matplotlib's concern and the slow
part of a report: the README only needs their file names (and a test stubs them out).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .catalog import reference_label
from .predictions import Predictions
from .report_tables import CAP_MARK, _best, _contenders
from .families import FAMILIES


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

    ok = _contenders(rows)  # the figures compare families' best rows: reference rows are in the tables
    made = _rmse_bars(out_dir, ok)
    for scenario in (preds.scenarios() if preds is not None else []):
        test = preds.test(scenario)
        if not test:
            continue
        k = int(np.random.default_rng(seed).integers(len(test)))
        made += _traces(out_dir, ok, preds, scenario, test, k)
        # Error vs contact force magnitude, tip force (where tip-force rows ran).
        if any(r["task"] == "tip_force" and r["scenario"] == scenario for r in ok) and "tip_force" in test[k]:
            made.append(_error_vs_force(out_dir, ok, preds, scenario, test))
    return made


def _rmse_bars(out_dir: Path, ok) -> list[str]:
    """``rmse_by_family_<task>.png``: the best model per family, per scenario and task."""
    import matplotlib.pyplot as plt

    made = []
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
    return made


def _traces(out_dir: Path, ok, preds: Predictions, scenario: str, test, k: int) -> list[str]:
    """``traces_<task>_<scenario>.png``: test instance ``k``'s target and each family's best row over time."""
    import matplotlib.pyplot as plt

    made = []
    inst = test[k]
    for task, target, unit in (("tip_force", "tip_force", "N"), ("joint_torque", "tau_m", "Nm")):
        models = [r for r in ok if r["task"] == task and r["scenario"] == scenario]
        if not models or target not in inst:
            continue
        picks = {}
        for fam in (f.name for f in FAMILIES.values() if "traces" in f.figures):
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
    return made


def _error_vs_force(out_dir: Path, ok, preds: Predictions, scenario: str, test) -> str:
    """``error_vs_force_<scenario>.png``: the RMS tip-force error of each family's best row by contact force."""
    import matplotlib.pyplot as plt

    f_true = np.concatenate([i.get("tip_force_truth", i["tip_force"]) for i in test])
    mag = np.linalg.norm(f_true, axis=1)
    bins = np.array([0, 1, 5, 10, 15, 20, np.inf])
    which = np.digitize(mag, bins) - 1
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    for fam in (f.name for f in FAMILIES.values() if "error-vs-force" in f.figures):
        b = _best(ok, "tip_force", scenario, lambda r, fam=fam: r["family"] == fam)
        fam_preds = preds.get(scenario, "tip_force", b["model"]) if b else None
        if fam_preds is None:
            continue
        err = np.linalg.norm(np.concatenate(fam_preds) - np.concatenate([i["tip_force"] for i in test]), axis=1)
        err = np.where(np.isnan(err), np.inf, err)  # a refused sample (NaN) is left out of its bin below
        vals = [np.sqrt(np.mean(e[np.isfinite(e)] ** 2)) if np.isfinite(e).any() else np.nan
                for e in (err[which == i] for i in range(len(bins) - 1))]
        ax.plot(range(len(vals)), vals, "o-", label=f"{fam}: {b['model']}")
    ax.set_xticks(range(len(bins) - 1), ["0-1", "1-5", "5-10", "10-15", "15-20", ">20"])
    ax.set_xlabel("|F_tip| true [N]")
    ax.set_ylabel("RMS of |error| [N]")
    ax.set_title(f"{scenario}: tip-force error vs contact force")
    ax.legend(fontsize=8)
    return _save(fig, out_dir, f"error_vs_force_{scenario}.png", dpi=110)


def learning_curve_figures(out_dir: Path, curves: dict) -> list[str]:
    """``learning_curves_<scenario>.png``: one panel per learned row, train and validation loss per epoch.

    ``curves`` is curves.json (``results.write_curves``): scenario -> model -> {task, epochs, stopped_by,
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

