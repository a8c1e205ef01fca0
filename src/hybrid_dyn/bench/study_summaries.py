"""What a study writes (``Study.summary``): one function per kind, from a :class:`~.studies.StudyRun`.

- ``data-scaling``: per scenario and task, the test RMSE of each family's best learned row against the
  number of training instances, beside the best physics row (flat: it trains on nothing); README.md,
  data_scaling.json and a log-log figure, data_scaling.png.
- ``controls`` (each variant a control arm): per scenario, task and row, each variant's validation loss against the reference point's
  (what every choice is read on), its change, and the test RMSE and nMSE for reference only; with a
  tolerance, whether the variant's gain stays under it (a longer budget that gains less: converged).
  README.md and ``<study>.json``.
- ``compare``: each variant's report against the reference report, every learned row divided by its own
  report's best analytic row (``compare.compare_reports``); README.md and ``<study>.json``.

Every summary names the command that wrote it. Test figures never choose anything here.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from .rows import is_physics_family

UNITS = {"tip_force": "N", "joint_torque": "Nm"}


def _command() -> str:
    return " ".join(["hybrid-dyn", *sys.argv[1:]])


def _write(out: Path, name: str, lines: list, summary: dict) -> None:
    """The summary's JSON first (it marks the folder as the study's: ``studies.check_study_dir``), then README.md."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(summary, indent=1) + "\n")
    (out / "README.md").write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------------------------------- data scaling
def data_scaling(run, out: Path) -> dict:
    """The ``data-scaling`` summary of ``run`` (a :class:`~.studies.StudyRun`), written to ``out``."""
    study = run.study
    n_train = run.train_instances()
    points = {n: run.points[f"train-{n}"] for n in study.train_instances}
    summary = summarise(study, run.chosen, points, n_train)
    write_data_scaling(Path(out), summary)
    return summary


def summarise(study, chosen: dict, points: dict, n_train: int) -> dict:
    """Per (scenario, task): the physics rows and each family's learned row, test RMSE per training size."""

    out = {"study": study.name, "profile": study.profile, "full_train_instances": n_train,
           "sizes": [*study.train_instances, n_train], "command": _command(), "panels": []}
    by_key = {n: {(r["scenario"], r["task"], r["model"]): r for r in rows if r.get("status") == "ok"}
              for n, rows in points.items()}
    for scenario, task in sorted({(k[0], k[1]) for k in chosen}):
        panel = {"scenario": scenario, "task": task, "unit": UNITS[task], "lines": []}
        for (s, t, family), r in sorted(chosen.items(), key=lambda kv: not is_physics_family(kv[0][2])):
            if (s, t) != (scenario, task):
                continue
            rmse = [float(by_key[n][(s, t, r["model"])]["rmse"]) if (s, t, r["model"]) in by_key[n] else None
                    for n in study.train_instances] + [float(r["rmse"])]
            if is_physics_family(family):  # does not use the training instances
                rmse = [float(r["rmse"])] * len(rmse)
            panel["lines"].append({"family": family, "model": r["model"], "rmse": rmse})
        out["panels"].append(panel)
    return out


def write_data_scaling(out: Path, summary: dict) -> None:
    """``README.md`` (a table per panel), ``data_scaling.json`` and ``data_scaling.png`` (log-log)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    (out / "data_scaling.json").write_text(json.dumps(summary, indent=1) + "\n")  # first: the folder's mark
    sizes = summary["sizes"]
    lines = [f"# Study `{summary['study']}` on profile `{summary['profile']}`", "",
             f"Produced by `{summary['command']}`. Test RMSE on the profile's full test split; each learned row "
             "retrained at the same step budget on the first N training instances (val in proportion); the "
             f"last column is the profile's own report ({summary['full_train_instances']} instances). Rows were "
             "chosen on the full report's validation loss. Physics rows do not learn from the training instances "
             "(the identified ones are fitted on the profile's own excitation experiment): flat. `physics` is "
             "the best physics row on validation; `physics on ...` the best one reading no more than a learned "
             "row reads, its fair comparator where the best reads a sensor that row does not.", ""]
    panels = summary["panels"]
    fig, axes = plt.subplots(1, max(1, len(panels)), figsize=(5.5 * max(1, len(panels)), 4.2), squeeze=False)
    for ax, panel in zip(axes[0], panels):
        unit = panel["unit"]
        lines += [f"## {panel['scenario']}, {panel['task']} [{unit}]", "",
                  "| family | row | " + " | ".join(f"N = {n}" for n in sizes) + " |",
                  "|---|---|" + "---|" * len(sizes)]
        for line in panel["lines"]:
            cells = ["" if v is None else f"{v:.4g}" for v in line["rmse"]]
            lines.append(f"| {line['family']} | `{line['model']}` | " + " | ".join(cells) + " |")
            xs = [n for n, v in zip(sizes, line["rmse"]) if v is not None and v > 0 and math.isfinite(v)]
            ys = [v for v in line["rmse"] if v is not None and v > 0 and math.isfinite(v)]
            style = (dict(ls="--" if line["family"] == "physics" else ":", color="k")
                     if is_physics_family(line["family"]) else dict(marker="o"))
            ax.plot(xs, ys, label=f"{line['model']} ({line['family']})", **style)
        lines.append("")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("training instances")
        ax.set_ylabel(f"test RMSE [{unit}]")
        ax.set_title(f"{panel['scenario']}: {panel['task']}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "data_scaling.png", dpi=120)
    plt.close(fig)
    lines += ["![data scaling](data_scaling.png)", ""]
    (out / "README.md").write_text("\n".join(lines))


# -------------------------------------------------------------------------------------------- controls
def _figures(r: dict) -> dict:
    """What a controls table quotes of one results.csv row."""
    if r.get("status") != "ok":
        return {"status": r.get("status"), "error": r.get("error", "")}
    num = lambda k: float(r[k]) if r.get(k) not in (None, "") else None  # noqa: E731
    return {"status": "ok", "val_loss": num("val_loss"), "rmse": num("rmse"), "nmse": num("nmse"),
            "epochs": r.get("epochs") or None, "stopped_by": r.get("stopped_by") or None}


def control_arms(run, out: Path) -> dict:
    """Each variant's validation loss against the reference point's, per scenario, task and row."""
    study = run.study
    key = lambda r: (r["scenario"], r["task"], r["model"])  # noqa: E731
    reference = {key(r): r for r in run.reference if r.get("status") == "ok"}
    ref_label = "the profile's report" if study.base.is_empty() else f"{study.base.describe()} (variant `base`)"
    panels = []
    for scenario, task in sorted({k[:2] for k in reference if k[2] in run.rows}):
        lines = []
        for model in run.rows:
            ref = reference.get((scenario, task, model))
            if ref is None:
                continue
            entries = [{"variant": "reference", "changes": ref_label, **_figures(ref)}]
            for variant, results in run.points.items():
                mine = next((r for r in results if key(r) == (scenario, task, model)), None)
                if mine is None:
                    continue
                e = {"variant": variant, "changes": study.variants[variant].describe(), **_figures(mine)}
                if e["status"] == "ok" and entries[0]["val_loss"]:
                    e["val_change"] = e["val_loss"] / entries[0]["val_loss"] - 1
                    if study.tolerance is not None:
                        e["converged"] = -e["val_change"] < study.tolerance
                entries.append(e)
            lines.append({"model": model, "entries": entries})
        panels.append({"scenario": scenario, "task": task, "unit": UNITS[task], "rows": lines})
    summary = {"study": study.name, "profile": study.profile, "description": study.description,
               "command": _command(), "reference": ref_label, "tolerance": study.tolerance, "panels": panels}
    _write(Path(out), study.name, controls_markdown(summary), summary)
    return summary


def controls_markdown(summary: dict) -> list:
    tol = summary["tolerance"]
    lines = [f"# Study `{summary['study']}` on profile `{summary['profile']}`", "",
             f"{summary['description'][0].upper()}{summary['description'][1:]}.", "",
             f"Produced by `{summary['command']}`. Reference: {summary['reference']}. Every variant is read on "
             "the validation loss (standardized MSE); test figures are for reference only, nothing was chosen on "
             "them." + (f" Converged: the variant lowers the validation loss by less than {tol:.0%}." if tol else ""),
             ""]
    n_failed = 0
    for panel in summary["panels"]:
        unit = panel["unit"]
        lines += [f"## {panel['scenario']}, {panel['task'].replace('_', ' ')}", "",
                  f"| row | variant | changes | epochs (stop) | val loss | val vs reference | test RMSE [{unit}] | "
                  "test nMSE |" + (" converged |" if tol else ""),
                  "|---|---|---|---|---|---|---|---|" + ("---|" if tol else "")]
        for line in panel["rows"]:
            for e in line["entries"]:
                if e["status"] != "ok":
                    n_failed += 1
                    lines.append(f"| {line['model']} | {e['variant']} | {e['changes']} | {e['status']}: "
                                 f"{e.get('error', '')} | | | | |" + (" |" if tol else ""))
                    continue
                change = f"{e['val_change']:+.1%}" if "val_change" in e else ""
                stop = f"{e['epochs']} ({e['stopped_by']})" if e["epochs"] else "-"
                conv = "" if not tol else {True: " yes |", False: " NO |"}.get(e.get("converged"), " |")
                lines.append(f"| {line['model']} | {e['variant']} | {e['changes']} | {stop} | {e['val_loss']:.5f} | "
                             f"{change} | {_g(e['rmse'])} | {_g(e['nmse'])} |{conv}")
        lines.append("")
    if n_failed:
        lines.append(f"{n_failed} run(s) failed: their error is in the table.")
    return lines


def _g(v) -> str:
    return "" if v is None else f"{v:.4f}"


# --------------------------------------------------------------------------------------------- compare
def compare(run, out: Path) -> dict:
    """Each variant's report against the reference report (``compare.compare_reports``)."""
    from .compare import compare_reports

    study, out = run.study, Path(out)
    lines = [f"# Study `{study.name}` on profile `{study.profile}`", "",
             f"{study.description[0].upper()}{study.description[1:]}.", "", f"Produced by `{_command()}`. "
             f"Reference: the profile's report (`{run.report}`); each variant's bench report is in its folder here.",
             ""]
    for variant, dirs in run.dirs.items():
        for where in dirs:
            text = compare_reports(where, run.report, labels=(variant, study.profile))
            lines += ["#" + text.replace("\n## ", "\n### "), ""]  # each comparison one level down
    summary = {"study": study.name, "profile": study.profile, "command": _command(),
               "variants": {v: [str(d) for d in dirs] for v, dirs in run.dirs.items()}}
    _write(out, study.name, lines, summary)
    return summary


SUMMARY_KINDS = {"data-scaling": data_scaling, "controls": control_arms, "compare": compare}
