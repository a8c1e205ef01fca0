"""Studies: a bench profile run again with one thing varied, and what changed.

A study is data (:class:`Study`): the profile it varies, the values of the one knob it
turns, and which rows it reruns. It runs through the harness (``run_bench``: same data,
same caches, same resume, same test split and scoring) and summarises the variants
beside the profile's own report, which is the study's full-data point.

``data-scaling`` (issue 31): how much data does learning need to reach the physics rows,
and does it ever? For the best learned row of each family and task (chosen on the full
report's *validation* loss, never its test figures), the rows are retrained at the same
step budget on the first N training instances (``TrainConfig.train_instances``; val cut
in proportion) and scored on the same full test split. The physics rows need no training
data (the identified ones fit on their own excitation run), so they are flat lines.

Run: ``hybrid-dyn study data-scaling`` (after ``hybrid-dyn bench --profile seed-sim``); the
variants' bench reports go to ``runs/studies/<study>/``, the summary to ``--out``
(default ``reports/<profile>/<study>``).
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

from ..errors import UsageError
from .catalog import get_row
from .integrity import read_run_json
from .profiles import get_profile
from .results import read_results
from .rows import is_physics_result

UNITS = {"tip_force": "N", "joint_torque": "Nm"}
LEARNED_FAMILIES = ("seed-net", "residual", "delan", "identified")  # families with trained rows


@dataclass(frozen=True)
class Study:
    """One knob of a profile turned. profile: the bench profile varied (its report is the full-data
    point). train_instances: the training-set sizes of the variants (instances; val in proportion)."""

    name: str
    profile: str
    description: str
    train_instances: tuple

    def base_profile(self):
        """The bench profile this study varies (``profiles.PROFILES``)."""
        return get_profile(self.profile)

    def variant(self, n: int, rows: tuple):
        """The profile of one variant: the chosen rows only, trained on ``n`` instances."""
        base = self.base_profile()
        return dataclasses.replace(base, name=f"{base.name}--{self.name}-{n}", families=(), rows=tuple(rows),
                                   train={**base.train, "train_instances": int(n)})


STUDIES = {
    "data-scaling": Study(
        name="data-scaling", profile="seed-sim", train_instances=(10, 40, 160),
        description="test error against the number of training instances (val in proportion), the best learned "
                    "row of each family and task at the same step budget, and the best physics rows"),
}


def get_study(name: str) -> Study:
    if name not in STUDIES:
        raise UsageError(f"unknown study {name!r}; known: {', '.join(STUDIES)}")
    return STUDIES[name]


def _ok(rows) -> list[dict]:
    return [r for r in rows if r.get("status") == "ok" and r.get("val_loss") not in (None, "")]


def choose_rows(full: list[dict]) -> dict:
    """(scenario, task, family) -> the learned row of lowest *validation* loss in the full report, and
    (scenario, task, "physics") -> the physics row of lowest validation loss. Validation, not test: the
    study must not pick its rows on the figures it reports."""
    best = {}
    for r in _ok(full):
        row = get_row(r["model"])
        if row.reference is not None:
            continue
        if row.trains and row.family in LEARNED_FAMILIES:
            key = (r["scenario"], r["task"], row.family)
        elif is_physics_result(r):
            key = (r["scenario"], r["task"], "physics")
        else:
            continue
        if key not in best or float(r["val_loss"]) < float(best[key]["val_loss"]):
            best[key] = r
    return best


def read_full_report(study: Study, report: Path) -> list[dict]:
    """The profile's own report: the study's full-data point. Refused unless it is a report of that profile."""
    meta = read_run_json(report)
    if meta is None or not (report / "results.csv").is_file():
        raise UsageError(f"{report} holds no bench report; run `hybrid-dyn bench --profile {study.profile} "
                         f"--out {report}` first (the study's full-data point)")
    if meta["profile"] != study.base_profile().to_dict():
        raise UsageError(f"{report} is a report of another profile or size than {study.profile!r}: rerun the bench")
    return read_results(report / "results.csv")


def run_study(study: Study, report: Path, out: Path, work_root: Path = Path("runs"), data_root=None,
              executor=None, log=print) -> dict:
    """Run every variant through the harness (resumable: each is a bench report under
    ``work_root/studies``), then write the summary to ``out``; returns the summary's data."""
    from .runner import run_bench

    full = read_full_report(study, Path(report))
    chosen = choose_rows(full)
    learned = tuple(dict.fromkeys(r["model"] for k, r in chosen.items() if k[2] != "physics"))
    n_train = _train_instances(Path(report))
    points = {}
    for n in study.train_instances:
        if n >= n_train:
            raise UsageError(f"study {study.name}: {n} training instances asked for, the full report trained on "
                             f"{n_train}")
        log(f"[study] {study.name}: {len(learned)} rows on {n} training instances")
        variant_dir = Path(work_root) / "studies" / study.name / f"train-{n}"
        rows = run_bench(study.variant(n, learned), variant_dir, data_root=data_root, work_root=work_root,
                         executor=executor, log=log)
        points[n] = rows
    summary = summarise(study, chosen, points, n_train)
    write_summary(Path(out), summary)
    return summary


def _train_instances(report: Path) -> int:
    """How many training instances the full report's model saw (its dataset's train split; one dataset)."""
    from ..data import load_dataset

    datasets = read_run_json(report).get("datasets", {})
    if len(datasets) != 1:
        raise UsageError(f"a study varies a one-dataset profile; {report} holds {len(datasets)} datasets")
    (info,) = datasets.values()
    return len(load_dataset(info["path"]).split("train"))


def summarise(study: Study, chosen: dict, points: dict, n_train: int) -> dict:
    """Per (scenario, task): the physics row and each family's learned row, test RMSE per training size."""
    out = {"study": study.name, "profile": study.profile, "full_train_instances": n_train,
           "sizes": [*study.train_instances, n_train], "command": f"hybrid-dyn study {study.name}",
           "panels": []}
    by_key = {n: {(r["scenario"], r["task"], r["model"]): r for r in rows if r.get("status") == "ok"}
              for n, rows in points.items()}
    for scenario, task in sorted({(k[0], k[1]) for k in chosen}):
        panel = {"scenario": scenario, "task": task, "unit": UNITS[task], "lines": []}
        for (s, t, family), r in sorted(chosen.items(), key=lambda kv: kv[0][2] != "physics"):
            if (s, t) != (scenario, task):
                continue
            rmse = [float(by_key[n][(s, t, r["model"])]["rmse"]) if (s, t, r["model"]) in by_key[n] else None
                    for n in study.train_instances] + [float(r["rmse"])]
            if family == "physics":
                rmse = [float(r["rmse"])] * len(rmse)
            panel["lines"].append({"family": family, "model": r["model"], "rmse": rmse})
        out["panels"].append(panel)
    return out


def write_summary(out: Path, summary: dict) -> None:
    """``README.md`` (a table per panel), ``data_scaling.json`` and ``data_scaling.png`` (log-log)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    sizes = summary["sizes"]
    lines = [f"# Study `{summary['study']}` on profile `{summary['profile']}`", "",
             f"Produced by `{summary['command']}`. Test RMSE on the profile's full test split; each learned row "
             "retrained at the same step budget on the first N training instances (val in proportion); the "
             f"last column is the profile's own report ({summary['full_train_instances']} instances). Rows were "
             "chosen on the full report's validation loss. Physics rows train on nothing: flat.", ""]
    panels = summary["panels"]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.2), squeeze=False)
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
            style = dict(ls="--", color="k") if line["family"] == "physics" else dict(marker="o")
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
    (out / "data_scaling.json").write_text(json.dumps(summary, indent=1) + "\n")
