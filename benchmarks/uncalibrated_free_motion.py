"""The estimator without a calibration on the real Panda's free-motion log (the true tip force is about 0): what its
error bar promises there, scored on the log's test part as ``benchmarks/free_motion.py`` scores the calibrated rows.
Per torque model (the description's, the identified file's with its friction) and method: the phantom |F| RMS,
the share of ``ok`` calls, the share of ``ok`` calls whose |F| lies within 2 |sigma|, and the statuses seen.

    python benchmarks/uncalibrated_free_motion.py [--work runs/free-motion] [--out reports/real] [--print-only]

Reads the imported logs and the identified files that ``benchmarks/free_motion.py`` left in --work; writes
``uncalibrated_free_motion.md`` into --out and redraws its README's section "Tip force in free motion"."""
from __future__ import annotations

import argparse
import collections
from pathlib import Path

import numpy as np

from hybrid_dyn.bench.free_motion import LOGS, METHODS, rows_in_split, score
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.logs.importer import read_spec
from hybrid_dyn.data.logs.real_logs import real_spec_path
from hybrid_dyn.estimator.replay import replay_log


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default="runs/free-motion")
    ap.add_argument("--out", default="reports/real")
    ap.add_argument("--print-only", action="store_true", help="print the table, write nothing (also runs on an "
                    "older checkout's estimator: PYTHONPATH=<its src>)")
    args = ap.parse_args()
    work, out = Path(args.work), Path(args.out)
    lines = ["| robot | torque model | method | phantom RMS [N] | ok | ok within 2 sigma | statuses (test part) |",
             "|---|---|---|---|---|---|---|"]
    for log in LOGS:
        spec, test = read_spec(real_spec_path(log)), load_dataset(work / log).split("test")
        identified = work / f"{log}-identified.json"
        for label, params in (("description", None), ("identified+friction", identified)):
            for method in METHODS:
                replay, _ = replay_log(spec, method, params=params)
                keep = rows_in_split(replay, test)
                s = score(replay, keep)
                seen = collections.Counter(np.array(replay.status)[keep]).most_common(3)
                within = "-" if np.isnan(s["ok_within_2sigma"]) else f"{100 * s['ok_within_2sigma']:.0f} %"
                lines.append(f"| {log.removeprefix('real-')} | {label} | {method} | {s['phantom_rms_N']:.2f} "
                             f"| {100 * s['share_ok']:.1f} % | {within} | {', '.join(f'{k} {v}' for k, v in seen)} |")
                print(lines[-1], flush=True)
    if args.print_only:
        return
    from hybrid_dyn.bench.free_motion import UNCALIBRATED, insert_section, section_lines

    (out / UNCALIBRATED).write_text("\n".join(lines) + "\n")
    insert_section(out / "README.md", section_lines(out))
    print(f"written: {out / UNCALIBRATED}, {out / 'README.md'}")


if __name__ == "__main__":
    main()
