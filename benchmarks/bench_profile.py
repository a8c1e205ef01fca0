"""Where a bench's time goes (issue 40): one ``hybrid-dyn bench`` run from empty caches, its wall and CPU
time, split per phase and per row family from the files it writes (run.json's invocation CPU, results.csv's
``train_cpu_seconds`` and ``score_cpu_seconds``).

By default the bench is issue 40's small case: ``hybrid-dyn bench --data`` on a 30 s, 7-joint Panda log at
100 Hz (3000 samples, built and imported by ``benchmarks/small_log.py``) with ``--families
analytic,identified``, whose floor is <= 90 s wall on 2 cores. The bench runs as a command of its own
(``python -m hybrid_dyn.cli``), timed from outside by :class:`hybrid_dyn.timing.Stopwatch` (wall; CPU of
the finished child, every worker included); the machine's load average and the busiest other processes are
recorded before and after, since the machine may be shared.

Phases: dataset (made or read, wall, run.json), training (the rows' training CPU), scoring (the rows'
scoring CPU), the rest (the invocation's CPU less the two: start-up, imports, predictions.h5,
results.csv, the report's tables and figures).

    PYTHONPATH=src nice .venv/bin/python benchmarks/bench_profile.py --out reports/performance/bench-small-log
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

FLOOR_SECONDS = 90.0  # issue 40: the small log with analytic,identified, on 2 cores


def busiest_processes(n: int = 5) -> list[str]:
    """The ``n`` processes with the most CPU, as ``ps`` prints them (what else ran on the machine)."""
    try:
        out = subprocess.run(["ps", "-eo", "pcpu,etime,comm", "--sort=-pcpu"], capture_output=True, text=True,
                             timeout=10).stdout.splitlines()
    except (OSError, subprocess.SubprocessError):
        return []
    return [" ".join(line.split()) for line in out[1:n + 1]]


def _float(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def profile_tables(report: Path, wall: float, cpu: float) -> tuple[list[str], dict]:
    """Markdown lines and a JSON-able summary of the bench report at ``report``."""
    meta = json.loads((report / "run.json").read_text())
    with open(report / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    inv = meta["invocations"][-1]
    train = sum(_float(r.get("train_cpu_seconds")) for r in rows if r.get("status") == "ok")
    score = sum(_float(r.get("score_cpu_seconds")) for r in rows if r.get("status") == "ok")
    data = sum(d.get("dataset_seconds") or 0.0 for d in meta.get("datasets", {}).values())
    families = defaultdict(lambda: [0, 0.0, 0.0, 0.0])
    for r in rows:
        fam = families[r["family"]]
        fam[0] += 1
        fam[1] += _float(r.get("train_seconds"))
        fam[2] += _float(r.get("train_cpu_seconds"))
        fam[3] += _float(r.get("score_cpu_seconds"))
    lines = ["| phase | seconds | of the invocation's CPU |", "|---|---:|---:|",
             f"| dataset (made or read, wall) | {data:.1f} | - |",
             f"| training (CPU, every row) | {train:.1f} | {train / inv['cpu_seconds']:.0%} |",
             f"| scoring (CPU, every row) | {score:.1f} | {score / inv['cpu_seconds']:.0%} |",
             f"| the rest (CPU: start-up, files, report) | {inv['cpu_seconds'] - train - score:.1f} | "
             f"{(inv['cpu_seconds'] - train - score) / inv['cpu_seconds']:.0%} |",
             f"| **invocation** (run.json) | {inv['wall_seconds']:.1f} wall, {inv['cpu_seconds']:.1f} CPU | |",
             f"| **command** (from outside) | {wall:.1f} wall, {cpu:.1f} CPU | |",
             "", "| family | rows | train wall [s] | train CPU [s] | score CPU [s] |", "|---|---:|---:|---:|---:|"]
    lines += [f"| {k} | {v[0]} | {v[1]:.1f} | {v[2]:.1f} | {v[3]:.1f} |" for k, v in families.items()]
    lines += ["", "| row | family | status | train wall [s] | train CPU [s] | score CPU [s] |",
              "|---|---|---|---:|---:|---:|"]
    lines += [f"| {r['model']} | {r['family']} | {r['status']} | {_float(r.get('train_seconds')):.1f} | "
              f"{_float(r.get('train_cpu_seconds')):.1f} | {_float(r.get('score_cpu_seconds')):.1f} |" for r in rows]
    summary = {"wall_seconds": wall, "cpu_seconds": cpu, "invocation": inv, "dataset_seconds": data,
               "train_cpu_seconds": train, "score_cpu_seconds": score,
               "families": {k: dict(zip(("rows", "train_seconds", "train_cpu_seconds", "score_cpu_seconds"), v))
                            for k, v in families.items()},
               "rows": [{k: r.get(k) for k in ("model", "family", "status", "train_seconds", "train_cpu_seconds",
                                               "score_cpu_seconds", "rmse")} for r in rows]}
    return lines, summary


def main(argv=None) -> int:
    from hybrid_dyn.timing import Stopwatch

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True, help="folder for README.md and profile.json")
    ap.add_argument("--data", type=Path, default=None, help="a dataset (default: the 30 s small log, built here)")
    ap.add_argument("--families", default="analytic,identified")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        data = args.data
        if data is None:
            sys.path.insert(0, str(Path(__file__).parent))
            from small_log import import_small_log, write_log_csv

            data = Path(import_small_log(write_log_csv(tmp / "log.csv"), tmp / "small-log").path)
        argv_bench = [sys.executable, "-m", "hybrid_dyn.cli", "bench", "--data", str(data), "--families",
                      args.families, "--workers", str(args.workers), "--out", str(tmp / "report"),
                      "--data-root", str(tmp / "data"), "--work-root", str(tmp / "runs")]
        load_before, busy_before = os.getloadavg(), busiest_processes()
        with Stopwatch() as sw:
            run = subprocess.run(argv_bench, capture_output=True, text=True)
        load_after, busy_after = os.getloadavg(), busiest_processes()
        if run.returncode != 0:
            print(run.stdout[-3000:], run.stderr[-3000:])
            return run.returncode
        lines, summary = profile_tables(tmp / "report", sw.wall, sw.cpu)
    met = sw.wall <= FLOOR_SECONDS
    command = (f"hybrid-dyn bench --data {'<the 30 s small log>' if args.data is None else args.data.name} "
               f"--families {args.families} --workers {args.workers}")
    head = [f"# Bench profile: `{command}`", "",
            "Written by `python benchmarks/bench_profile.py` (from empty caches, one invocation). "
            "Data: " + ("`benchmarks/small_log.py`'s 30 s, 7-joint Panda log at 100 Hz (3000 samples), "
                        "imported in 10 blocks split 6/2/2 in time order." if args.data is None else f"`{args.data.name}`."),
            "", f"- wall {sw.wall:.1f} s, CPU {sw.cpu:.1f} s ({sw.cores:.2f} cores); issue 40's floor "
            f"<= {FLOOR_SECONDS:.0f} s wall on 2 cores: {'met' if met else 'NOT met'}"
            + ("" if args.data is None and args.families == "analytic,identified" else " (the floor is for the small log)"),
            f"- machine: {os.cpu_count()} cores; load average (1, 5, 15 min) before {tuple(round(v, 2) for v in load_before)}, "
            f"after {tuple(round(v, 2) for v in load_after)}",
            f"- busiest processes before: {'; '.join(busy_before)}", f"- busiest processes after: {'; '.join(busy_after)}",
            ""]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "README.md").write_text("\n".join(head + lines) + "\n")
    summary.update(command=command, load_before=load_before, load_after=load_after, busy_before=busy_before,
                   busy_after=busy_after, floor_seconds=FLOOR_SECONDS, floor_met=met)
    (args.out / "profile.json").write_text(json.dumps(summary, indent=1, default=str) + "\n")
    print("\n".join(head + lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
