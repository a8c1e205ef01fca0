"""The floors for a regenerated ``reports/default`` (issue 40's, tightened by issue 57): its cold invocation's
wall and CPU time, and every row against an earlier report.

Floors (this project's targets, so they live here and not in the report):
- the report's last invocation began on empty caches and did all of it: at most 60 min of wall time and
  6,500 CPU-seconds (the bench's process and its workers);
- every row of the earlier report is present, and its test RMSE is <= 1.02 x the earlier value
  (a lower one is welcome) where its scenario's data are the same (the same config hash in both run.json);
  a row on other data (a changed scenario) is listed beside its earlier figure without a floor, as are the
  rows the earlier report did not have, and the rows of the retired scenarios (RETIRED), which the default
  profile no longer runs.

The earlier report is read from git (``--before REV``, default 84c0303, the report issue 57 measured).
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

WALL_FLOOR_MIN = 60.0
CPU_FLOOR_SECONDS = 6500.0
RMSE_FLOOR_RATIO = 1.02
# The contact-step scenarios the default profile retired for its one, contact-steps-hardware: contact-steps scored
# every row as contact-steps-hardware did, contact-steps-quiet (the quieter base sensor) is a study's now.
RETIRED = ("contact-steps", "contact-steps-quiet")


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
    # The last invocation that began on empty caches (an earlier one, stopped, worked on caches it then lost):
    # the floors need it to be the last invocation too, one that did all of it.
    colds = [k for k, i in enumerate(inv) if i.get("cold_start")]
    first = inv[colds[-1]] if colds else {}
    cold, one = bool(colds), bool(colds) and colds[-1] == len(inv) - 1 and first.get("finished") is not None
    wall_min, cpu = first.get("wall_seconds", math.nan) / 60, first.get("cpu_seconds", math.nan)
    wall_ok, cpu_ok = cold and one and wall_min <= WALL_FLOOR_MIN, cold and one and cpu <= CPU_FLOOR_SECONDS
    spans = ", ".join(f"{i['wall_seconds'] / 60:.1f} min / {i.get('cpu_seconds', math.nan):.0f} CPU-s"
                      + (" (cold)" if i.get("cold_start") else "") for i in inv)
    phases = "; ".join(f"{k}: {v['wall_seconds']:.0f} s wall, {v['cpu_seconds']:.0f} CPU-s"
                       for k, v in (first.get("phases") or {}).items())
    lines = [f"# `{report}` regenerated: the floors against the report at {before}", "",
             "Printed by `python checks/default_regeneration.py` (floors: this project's targets, not findings).", "",
             f"- invocations: {spans}" + ("" if one else " (the floors need the last invocation to be a cold one that did it all)"),
             f"- wall time of the cold invocation {wall_min:.1f} min against {WALL_FLOOR_MIN:.0f}: "
             f"**{'met' if wall_ok else 'NOT met'}**",
             f"- its CPU {cpu:.0f} s against {CPU_FLOOR_SECONDS:.0f}: **{'met' if cpu_ok else 'NOT met'}**"
             + (f" ({cpu / first['wall_seconds']:.2f} cores on average)" if first.get("wall_seconds") else ""),
             *([f"- by phase: {phases}"] if phases else []), ""]
    new = {_key(r): r for r in read_results(report / "results.csv")}
    old = {_key(r): r for r in _rows_at(before, report)}
    hashes_now = {s: d.get("config_hash") for s, d in (run.get("datasets") or {}).items()}
    hashes_before = _hashes_at(before, report)
    lines += ["| task | scenario | row | RMSE before | RMSE now | ratio | floor <= 1.02 |", "|---|---|---|---|---|---|---|"]
    failed = []
    for key, o in old.items():
        a, b = _rmse(o), _rmse(new.get(key))
        if key[1] in RETIRED:
            verdict, ratio = "no floor (scenario retired)", math.nan
        elif key not in new:
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
    return lines, wall_ok and cpu_ok and not failed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--report", type=Path, default=Path("reports/default"))
    ap.add_argument("--before", default="84c0303", help="the git revision of the earlier report")
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
