"""Two bench reports side by side: each learned row against its own report's physics (``hybrid-dyn compare``).

Two reports made on different data (more instances, another split, another log) test on different
samples, so a row's RMSE in one is not comparable with its RMSE in the other. Each is divided by the
best *analytic* row of its own report, scenario and task (physics, on the same test samples, which
needs no training and does not care how much data there is):

    ratio = RMSE(row) / RMSE(best analytic row)      in each report

A learned row whose ratio falls from one report to the other gained from what changed (for two
amounts of data: it is data-limited); one whose ratio stays put is limited by its architecture or its
inputs. The ``data-control`` study (``bench/studies.py``) writes this comparison of a profile's report
against the same profile on less data.
"""
from __future__ import annotations

from pathlib import Path

from .integrity import read_checked_report
from .report_tables import best_row
from .families import FAMILIES


UNITS = {"tip_force": "N", "joint_torque": "Nm"}


def _ok(rows: list[dict]) -> dict:
    return {(r["scenario"], r["task"], r["model"]): r for r in rows if r.get("status") == "ok"}


def best_analytic(rows: list[dict]) -> dict:
    """(scenario, task) -> (model, rmse) of the lowest-RMSE analytic row (``report_tables.best_row``)."""
    best = {}
    for scenario, task in {(r["scenario"], r["task"]) for r in rows}:
        r = best_row(rows, task, scenario, lambda r: r["family"] == "analytic")
        if r is not None:
            best[(scenario, task)] = (r["model"], float(r["rmse"]))
    return best


def data_size(meta: dict) -> str:
    """Instances x trajectories per instance of a report's simulated scenarios, from its run.json (``meta``)."""
    over = meta["profile"].get("scenario_overrides")
    over = over if isinstance(over, dict) else {}
    sizes = {f"{v.get('n_instances')} x {tuple(v.get('trajectories') or ())}" for v in over.values()
             if isinstance(v, dict)}
    return ", ".join(sorted(sizes)) or "the generator's default"


def compare_reports(small: Path, large: Path, command: str | None = None, labels=None) -> str:
    """Markdown: per scenario and task, every learned row of both reports with its RMSE, its ratio to its own
    report's best analytic row, its epochs, and the change of the ratio from ``small`` to ``large``.
    ``labels``: the two reports' names in the tables (default: their folders' names)."""
    small, large = Path(small), Path(large)
    a_name, b_name = labels or (small.name, large.name)
    # Checked as ``hybrid-dyn report`` checks a folder before it draws: a hand-edited number, another report's
    # run.json or a user's is refused, naming the row or file, never printed (integrity.py).
    report_a, report_b = read_checked_report(small, replacing=False), read_checked_report(large, replacing=False)
    rows_a, rows_b = report_a.rows, report_b.rows
    a, b = _ok(rows_a), _ok(rows_b)
    pa, pb = best_analytic(rows_a), best_analytic(rows_b)
    out = [f"# `{small}` against `{large}`: each learned row against its own report's physics", ""]
    if command:
        out += [f"`{command}`", ""]
    out += [f"- {a_name}: `{small}`, instances x trajectories per instance: {data_size(report_a.meta)}",
            f"- {b_name}: `{large}`, instances x trajectories per instance: {data_size(report_b.meta)}", "",
            "Ratio: a row's test RMSE over the best analytic row's in the same report, scenario and task (the two "
            "reports test on different instances; physics needs no data). A ratio that falls with more data is "
            "data-limited.", ""]
    fitted = FAMILIES.names(fitted=True, in_studies=True, identifies_parameters=False)  # no identified fit
    for scenario, task in sorted({k[:2] for k in b} & {k[:2] for k in a}):
        if (scenario, task) not in pa or (scenario, task) not in pb:
            continue
        (ma, ra), (mb, rb) = pa[(scenario, task)], pb[(scenario, task)]
        table = []
        for (s, t, model), rl in b.items():
            if (s, t) != (scenario, task) or rl["family"] not in fitted or (s, t, model) not in a:
                continue
            rs = a[(s, t, model)]
            xs, xl = float(rs["rmse"]) / ra, float(rl["rmse"]) / rb
            table.append(f"| {model} | {rl['family']} | {float(rs['rmse']):.3f} | {xs:.2f} | "
                         f"{rs.get('epochs') or '-'} ({rs.get('best_epoch') or '-'}) | {float(rl['rmse']):.3f} | "
                         f"{xl:.2f} | {rl.get('epochs') or '-'} ({rl.get('best_epoch') or '-'}) | {xl / xs:.2f}x |")
        if not table:  # a scenario with physics rows only
            continue
        unit = UNITS[task]
        out += [f"## {scenario}, {task.replace('_', ' ')}", "",
                f"Best analytic row: {a_name} `{ma}` {ra:.3f} {unit}, {b_name} `{mb}` {rb:.3f} {unit}.", "",
                f"| model | family | {a_name} RMSE [{unit}] | {a_name} ratio | {a_name} epochs (best) | "
                f"{b_name} RMSE [{unit}] | {b_name} ratio | {b_name} epochs (best) | ratio change |",
                "|---|---|---|---|---|---|---|---|---|", *table, ""]
    return "\n".join(out)

