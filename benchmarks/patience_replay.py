"""What a budget patience would have done to a default report's learned rows, read off their recorded validation
curves: per patience P (rounds without improvement, as ``learn/train.py`` counts them: an improvement beats the best
by ``min_rel_delta`` x best), the training CPU after the stop (each row's ``train_cpu_seconds`` x its share of
rounds not run) and the rows whose kept round would change. A row that would stop is a prefix of the whole run
(the schedule is the whole budget's), so this is exact where the training is deterministic.

Run:
    .venv/bin/python benchmarks/patience_replay.py --rev 84c0303 --patience 8,10,12,15
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import subprocess


def _at(rev: str, path: str) -> str:
    return subprocess.run(["git", "show", f"{rev}:{path}"], capture_output=True, text=True, check=True).stdout


def replay(curves: dict, rows: dict, patience: int, min_rel_delta: float = 1e-4) -> tuple[float, float, list]:
    """(training CPU-s after the stops, all training CPU-s of the curves' rows, rows whose kept round changes)."""
    saved, total, changed = 0.0, 0.0, []
    for scenario, models in curves.items():
        for model, curve in models.items():
            val = [e["val_loss"] for e in curve["history"]]
            best, kept, idle, stop = curve["initial_val_loss"], -1, 0, len(val)
            for i, v in enumerate(val):
                if v < best - min_rel_delta * abs(best):
                    best, kept, idle = v, i, 0
                else:
                    idle += 1
                    if idle >= patience:
                        stop = i + 1
                        break
            cpu = float(rows[(scenario, model)].get("train_cpu_seconds") or 0.0)
            total += cpu
            saved += cpu * (1 - stop / len(val))
            if kept != curve["best_epoch"]:
                was = curve["initial_val_loss"] if curve["best_epoch"] < 0 else val[curve["best_epoch"]]
                now = curve["initial_val_loss"] if kept < 0 else val[kept]
                changed.append(f"{scenario}/{model} (round {curve['best_epoch']} -> {kept}, validation loss "
                               f"{now / was:.4f}x)")
    return saved, total, changed


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", default="84c0303", help="the git revision of the report")
    ap.add_argument("--report", default="reports/default")
    ap.add_argument("--patience", default="8,10,12,15")
    args = ap.parse_args(argv)
    curves = json.loads(_at(args.rev, f"{args.report}/curves.json"))
    rows = {(r["scenario"], r["model"]): r
            for r in csv.DictReader(io.StringIO(_at(args.rev, f"{args.report}/results.csv")))}
    n = sum(len(m) for m in curves.values())
    for p in (int(v) for v in args.patience.split(",")):
        saved, total, changed = replay(curves, rows, p)
        print(f"patience {p}: {saved:.0f} of {total:.0f} training CPU-s after the stop ({saved / total:.0%}); "
              f"{len(changed)} of {n} rows keep another round" + (f": {', '.join(changed)}" if changed else ""))


if __name__ == "__main__":
    main()
