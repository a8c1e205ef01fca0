"""Does the data or the architecture set the learned rows' limit? Two bench reports side by side (issue 14).

The same profile run on two amounts of data (for ``default``: 18 instances of 5-6 trajectories, and
40 of 5-10) gives each learned row two test RMSEs. The two runs have different test instances, so a
raw RMSE is not comparable between them; each is divided by the best *analytic* row of its own report,
scenario and task (physics, on the same test samples), which needs no training and does not care how
much data there is:

    ratio = RMSE(row) / RMSE(best analytic row)      in each report

A row whose ratio falls with more data is data-limited; one whose ratio stays put is limited by its
architecture or its inputs. The larger-capacity control (``tau-mlp-wide``, 2 x 128 with dropout, beside
the seed's 2 x 32 torque nets) reads the same way across rows within one report.

Run: .venv/bin/python benchmarks/data_control.py --small reports/data-control --large reports/default \\
         --out reports/default/data_control.md
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hybrid_dyn.bench.report import best_row
from hybrid_dyn.bench.runner import read_results

LEARNED = ("seed-net", "residual", "delan")


def _ok(rows: list[dict]) -> dict:
    return {(r["scenario"], r["task"], r["model"]): r for r in rows if r.get("status") == "ok"}


def best_analytic(rows: list[dict]) -> dict:
    """(scenario, task) -> (model, rmse) of the lowest-RMSE analytic row (``report.best_row``)."""
    best = {}
    for scenario, task in {(r["scenario"], r["task"]) for r in rows}:
        r = best_row(rows, task, scenario, lambda r: r["family"] == "analytic")
        if r is not None:
            best[(scenario, task)] = (r["model"], float(r["rmse"]))
    return best


def _size(report: Path) -> str:
    meta = json.loads((report / "run.json").read_text())
    over = meta.get("profile", {}).get("scenario_overrides") or {}
    sizes = {f"{v.get('n_instances')} x {tuple(v.get('trajectories', ()))}" for v in over.values()}
    return ", ".join(sorted(sizes)) or "the generator's default"


def compare(small: Path, large: Path) -> str:
    rows_a, rows_b = read_results(small / "results.csv"), read_results(large / "results.csv")
    a, b = _ok(rows_a), _ok(rows_b)
    pa, pb = best_analytic(rows_a), best_analytic(rows_b)
    unit = {"tip_force": "N", "joint_torque": "Nm"}
    out = [f"# Data control: `{small}` against `{large}`", "",
           f"`{' '.join(sys.argv)}`", "",
           f"- small: `{small}`, instances x trajectories per instance: {_size(small)}",
           f"- large: `{large}`, instances x trajectories per instance: {_size(large)}", "",
           "Ratio: a row's test RMSE over the best analytic row's in the same report, scenario and task (the two "
           "reports test on different instances; physics needs no data). A ratio that falls with more data is "
           "data-limited.", ""]
    for scenario, task in sorted({k[:2] for k in b} & {k[:2] for k in a}):
        if (scenario, task) not in pa or (scenario, task) not in pb:
            continue
        (ma, ra), (mb, rb) = pa[(scenario, task)], pb[(scenario, task)]
        table = []
        for (s, t, model), rl in b.items():
            if (s, t) != (scenario, task) or rl["family"] not in LEARNED or (s, t, model) not in a:
                continue
            rs = a[(s, t, model)]
            xs, xl = float(rs["rmse"]) / ra, float(rl["rmse"]) / rb
            table.append(f"| {model} | {rl['family']} | {float(rs['rmse']):.3f} | {xs:.2f} | "
                         f"{rs.get('epochs') or '-'} ({rs.get('best_epoch') or '-'}) | {float(rl['rmse']):.3f} | "
                         f"{xl:.2f} | {rl.get('epochs') or '-'} ({rl.get('best_epoch') or '-'}) | {xl / xs:.2f}x |")
        if not table:  # a scenario with physics rows only
            continue
        out += [f"## {scenario}, {task.replace('_', ' ')}", "",
                f"Best analytic row: small `{ma}` {ra:.3f} {unit[task]}, large `{mb}` {rb:.3f} {unit[task]}.", "",
                f"| model | family | small RMSE [{unit[task]}] | small ratio | small epochs (best) | "
                f"large RMSE [{unit[task]}] | large ratio | large epochs (best) | ratio change |",
                "|---|---|---|---|---|---|---|---|---|", *table, ""]
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", required=True, help="the report on less data")
    ap.add_argument("--large", required=True, help="the report on more data")
    ap.add_argument("--out", default=None, help="write the markdown here")
    args = ap.parse_args(argv)
    text = compare(Path(args.small), Path(args.large))
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
