"""Tip force in free motion on the real arms (``bench/free_motion.py``): writes ``free_motion.csv`` and
``free_motion.md`` into ``reports/real`` (or --out), and the section "Tip force in free motion" into its README.

    python benchmarks/free_motion.py [--work runs/free-motion] [--out reports/real]

The imported logs, identified files and calibrations go to --work and are reused by a rerun (a few minutes
from empty on 2 cores)."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from hybrid_dyn.bench.free_motion import free_motion_rows, insert_section, section_lines, write_table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default="runs/free-motion", help="imported logs, identified files, calibrations")
    ap.add_argument("--out", default="reports/real", help="where free_motion.csv and free_motion.md go")
    ap.add_argument("--section-only", action="store_true",
                    help="only redraw the README section from the free_motion.md already in --out")
    args = ap.parse_args()
    if args.section_only:
        insert_section(Path(args.out) / "README.md", section_lines(Path(args.out)))
        return
    t0 = time.perf_counter()
    rows = free_motion_rows(Path(args.work))
    for path in write_table(rows, Path(args.out)):
        print(f"written: {path}")
    readme = Path(args.out) / "README.md"
    if readme.exists():  # the report's section, as `hybrid-dyn report` draws it
        insert_section(readme, section_lines(Path(args.out)))
        print(f"section written: {readme}")
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
