"""A long ROS bag through `hybrid-dyn import` and `hybrid-dyn estimate`: wall time and peak memory.

A Panda motion at 1 kHz (``tests/helpers/ros_bags.py``: /joint_states and /ft_base, ROS 2 MCAP) of
``--minutes`` is written under a temporary folder (default /tmp, deleted after), then each command runs
in its own process under ``/usr/bin/time -v`` (its "Maximum resident set size" and elapsed time).
The floors (an hour's bag): import and estimate each under 1 GB peak, import under 2 min, estimate
under 4 min on 2 cores.

Run: nice -n 10 .venv/bin/python benchmarks/bag_scale.py --minutes 10 [--minutes 30] [--tmp /tmp]
Writes reports/performance/bags/README.md (one row per command and length, this run's numbers).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def write_long_bag(folder: Path, minutes: float) -> Path:
    from helpers.ros_bags import panda_signals, ros_spec, write_bag

    from hybrid_dyn.analytic.robot import load_robot

    n = int(minutes * 60_000)
    sig = panda_signals(load_robot("panda"), n=n, seed=11)
    bag = write_bag(folder / "run", sig, tip=False)
    del sig
    return ros_spec(folder / "spec", bag, tip=False)


def timed(cmd: list) -> dict:
    """Wall [s] and peak RSS [MB] of one command, from /usr/bin/time -v."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    t0 = time.perf_counter()
    p = subprocess.run(["/usr/bin/time", "-v", *cmd], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if p.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr[-3000:]}")
    rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr).group(1))
    return {"wall_s": wall, "peak_mb": rss_kb / 1024, "out": p.stdout}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, action="append")
    ap.add_argument("--tmp", default="/tmp")
    ap.add_argument("--out", default=str(ROOT / "reports/performance/bags/README.md"))
    args = ap.parse_args()
    cli = [sys.executable, "-m", "hybrid_dyn.cli"]
    rows = []
    print(f"load average: {os.getloadavg()}", flush=True)
    for minutes in args.minutes or [10.0]:
        folder = Path(tempfile.mkdtemp(prefix="bag_scale_", dir=args.tmp))
        try:
            t0 = time.perf_counter()
            spec = write_long_bag(folder, minutes)
            size = sum(p.stat().st_size for p in (folder / "run").rglob("*") if p.is_file())
            print(f"{minutes:g} min bag: {size / 1e9:.2f} GB written in {time.perf_counter() - t0:.0f} s", flush=True)
            imp = timed([*cli, "import", "--spec", str(spec), "--out", str(folder / "ds")])
            est = timed([*cli, "estimate", str(spec), "--method", "base-momentum", "--out", str(folder / "tip.csv")])
            for name, r in (("import", imp), ("estimate", est)):
                print(f"{name}: {r['wall_s']:.1f} s, {r['peak_mb']:.0f} MB peak", flush=True)
                rows.append((minutes, size, name, r))
        finally:
            shutil.rmtree(folder, ignore_errors=True)
    write_report(Path(args.out), rows)


def write_report(path: Path, rows: list) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = ["# ROS bags at scale: `hybrid-dyn import` and `hybrid-dyn estimate`", "",
             "Written by `benchmarks/bag_scale.py` (a Panda's /joint_states and /ft_base at 1 kHz, ROS 2 MCAP); each",
             "command in its own process under `/usr/bin/time -v`, on this repository's 2-core machine, niced,",
             "beside other work. Floors for a 1 h bag: import and estimate each < 1 GB peak; import < 2 min,",
             "estimate < 4 min.", "",
             "| bag | size | command | wall [s] | peak RSS [MB] |", "|---|---|---|---|---|"]
    for minutes, size, name, r in rows:
        lines.append(f"| {minutes:g} min | {size / 1e9:.2f} GB | {name} | {r['wall_s']:.1f} | {r['peak_mb']:.0f} |")
    by = {(m, n): r for m, _, n, r in rows}
    ms = sorted({m for m, *_ in rows})
    if len(ms) > 1:
        lines += ["", f"Per minute of bag between {ms[0]:g} and {ms[-1]:g} min (the slope; an hour extrapolated):", ""]
        for name in ("import", "estimate"):
            a, b = by[(ms[0], name)], by[(ms[-1], name)]
            dw, dm = (b["wall_s"] - a["wall_s"]) / (ms[-1] - ms[0]), (b["peak_mb"] - a["peak_mb"]) / (ms[-1] - ms[0])
            lines.append(f"- {name}: {dw:.2f} s and {dm:.1f} MB per minute -> 60 min: "
                         f"{a['wall_s'] + dw * (60 - ms[0]):.0f} s, {a['peak_mb'] + dm * (60 - ms[0]):.0f} MB")
    path.write_text("\n".join(lines) + "\n")
    print(f"written: {path}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
