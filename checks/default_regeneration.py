"""Issue 40's floors for a regenerated ``reports/default``: its wall time from cold, and every row against an earlier report.

Floors (this project's targets, so they live here and not in the report):
- the invocations recorded in run.json sum to <= 90 min, the first of them a cold start;
- every row of the earlier report is present, and its test RMSE is <= 1.02 x the earlier value
  (a lower one is welcome) where its scenario's data are the same (the same config hash in both run.json);
  a row on other data (a changed sensor model) is listed beside its earlier figure without a floor, as
  are the rows the earlier report did not have.

The earlier report is read from git (``--before REV``, default 4f1012e, the report the issue measured).
Run (after the bench):
    .venv/bin/python checks/default_regeneration.py --report reports/default \
        --out checks/acceptance/default-regeneration.md

Exit status: 0 when every floor is met, 1 when one is not.
"""
from __future__ import annotations

import argparse
import csv
import io
import math
import subprocess
import sys
from pathlib import Path

from hybrid_dyn.bench.integrity import read_run_json
from hybrid_dyn.bench.results import read_results

WALL_FLOOR_MIN = 90.0
RMSE_FLOOR_RATIO = 1.02


def _key(row: dict) -> tuple[str, str, str]:
    return row["task"], row["scenario"], row["model"]


def _rows_at(rev: str, report: Path) -> list[dict]:
    text = subprocess.run(["git", "show", f"{rev}:{report.as_posix()}/results.csv"], capture_output=True,
                          text=True, check=True).stdout
    return list(csv.DictReader(io.StringIO(text)))


def _rmse(row: dict | None) -> float:
    try:
        return float(row["rmse"]) if row and row.get("status") == "ok" else math.nan
    except (TypeError, ValueError):
        return math.nan


def _hashes_at(rev: str, report: Path) -> dict:
    """scenario -> config hash of the datasets the report at ``rev`` was computed on (its run.json)."""
    import json

    text = subprocess.run(["git", "show", f"{rev}:{report.as_posix()}/run.json"], capture_output=True, text=True,
                          check=True).stdout
    return {s: d.get("config_hash") for s, d in (json.loads(text).get("datasets") or {}).items()}


def check(report: Path, before: str) -> tuple[list[str], bool]:
    """The check's markdown lines and whether every floor is met."""
    run = read_run_json(report, replacing=False)
    if run is None:
        raise SystemExit(f"{report}: no run.json (not a bench report, or the bench has not started)")
    inv = run.get("invocations", [])
    total_min = sum(i["wall_seconds"] for i in inv) / 60
    cold = bool(inv) and inv[0].get("cold_start", False)
    wall_ok = cold and total_min <= WALL_FLOOR_MIN
    cpu = run.get("cpu_seconds")
    spans = ", ".join(f"{i['wall_seconds'] / 60:.1f}" + (" (cold)" if i.get("cold_start") else "") for i in inv)
    lines = [f"# `{report}` regenerated: issue 40's floors against the report at {before}", "",
             "Printed by `python checks/default_regeneration.py` (floors: this project's targets, not findings).", "",
             f"- invocations [min]: {spans}; "
             f"in all {total_min:.1f} min against {WALL_FLOOR_MIN:.0f}: **{'met' if wall_ok else 'NOT met'}**"
             + (f"; CPU of the last invocation {cpu / 60:.1f} min" if isinstance(cpu, (int, float)) else ""), ""]
    new = {_key(r): r for r in read_results(report / "results.csv")}
    old = {_key(r): r for r in _rows_at(before, report)}
    hashes_now = {s: d.get("config_hash") for s, d in (run.get("datasets") or {}).items()}
    hashes_before = _hashes_at(before, report)
    lines += ["| task | scenario | row | RMSE before | RMSE now | ratio | floor <= 1.02 |", "|---|---|---|---|---|---|---|"]
    failed = []
    for key, o in old.items():
        a, b = _rmse(o), _rmse(new.get(key))
        if key not in new:
            verdict, ratio = "**NOT met** (missing)", math.nan
        elif math.isnan(a):
            verdict, ratio = "no floor (no RMSE before)", math.nan
        elif hashes_now.get(key[1]) != hashes_before.get(key[1]):
            verdict, ratio = f"no floor (other data: config hash {hashes_before.get(key[1])} now {hashes_now.get(key[1])})", b / a
        else:
            ratio = b / a
            verdict = "met" if ratio <= RMSE_FLOOR_RATIO else "**NOT met**"
        if verdict.startswith("**"):
            failed.append(key)
        lines.append(f"| {key[0]} | {key[1]} | {key[2]} | {a:.4g} | {b:.4g} | {ratio:.3f} | {verdict} |")
    added = [k for k in new if k not in old]
    lines += ["", f"Rows met: {len(old) - len(failed)} of {len(old)}; not met: {len(failed)}"
              + (" (" + "; ".join("/".join(k) for k in failed) + ")" if failed else "") + ".", "",
              f"Rows the earlier report did not have (no floor): {len(added)}"
              + (": " + ", ".join("/".join(k) + f" {_rmse(new[k]):.4g}" for k in added) if added else "") + "."]
    return lines, wall_ok and not failed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--report", type=Path, default=Path("reports/default"))
    ap.add_argument("--before", default="4f1012e", help="the git revision of the earlier report")
    ap.add_argument("--out", type=Path, help="also write the check to this markdown file")
    args = ap.parse_args(argv)
    lines, ok = check(args.report, args.before)
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
