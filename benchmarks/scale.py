"""Generation throughput through each executor (issue 9), measured in this one run.

  local, 1 worker    generate_dataset in this process
  local, 2 workers   two spawned processes (ProcessExecutor)
  ray, 2 workers     Ray tasks on a local 2-CPU Ray instance (RayExecutor); its start-up
                     (ray.init) is timed apart: on a cluster it is paid once, not per dataset

All three write the same dataset (checked byte for byte). The Ray overhead is
ray_wall / local_2_wall - 1, with and without the start-up; the target is
under 15 % at `default` scale (the default profile's instances: 5-20
trajectories each). Runs alternate between executors, medians are quoted.

Run: .venv/bin/python benchmarks/scale.py [--scenario paper-ext] [--instances 40] [--repeats 1] [--out FILE]
(default --out: reports/performance/scale/results.json)
The machine's load average is printed first: the numbers need two otherwise idle cores.
"""
import argparse
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from hybrid_dyn.data import load_dataset
from hybrid_dyn.sim.executors import ProcessExecutor, RayExecutor, SerialExecutor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.scenarios import scenario_config
from hybrid_dyn.timing import Stopwatch


def tree_bytes(path: Path) -> dict:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


def timed_generation(cfg, out: Path, executor) -> float:
    with Stopwatch() as sw:
        generate_dataset(cfg, out, executor=executor, progress=False)
    return sw.wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-ext")
    ap.add_argument("--instances", type=int, default=None, help="default: the default profile's 40")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--out", default="reports/performance/scale/results.json", help="where to write the numbers as JSON")
    args = ap.parse_args()
    import ray

    load_before = os.getloadavg()[0]
    print(f"load average before: {load_before:.2f} on {os.cpu_count()} cores")
    overrides = {"n_instances": args.instances} if args.instances else {}
    cfg = scenario_config(args.scenario, "default", **overrides)
    walls = {"local-1": [], "local-2": [], "ray-2": []}
    ray_init = []
    same = True
    samples = None
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(args.repeats):
            dirs = {k: Path(tmp) / f"r{rep}-{k}" for k in walls}
            walls["local-1"].append(timed_generation(cfg, dirs["local-1"], SerialExecutor()))
            walls["local-2"].append(timed_generation(cfg, dirs["local-2"], ProcessExecutor(2)))
            with Stopwatch() as sw:
                ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="ERROR",
                         object_store_memory=100 * 2**20)
            ray_init.append(sw.wall)
            try:
                walls["ray-2"].append(timed_generation(cfg, dirs["ray-2"], RayExecutor()))  # uses the running Ray
            finally:
                ray.shutdown()
            ref = tree_bytes(dirs["local-1"])
            same &= ref == tree_bytes(dirs["local-2"]) == tree_bytes(dirs["ray-2"])
            samples = load_dataset(dirs["local-1"]).meta["n_samples"]
            for d in dirs.values():
                shutil.rmtree(d)
    med = {k: float(np.median(v)) for k, v in walls.items()}
    init = float(np.median(ray_init))
    sim_seconds = samples / cfg.record_hz
    print(f"generate {args.scenario}/default: {cfg.n_instances} instances, {samples} samples "
          f"({sim_seconds:.0f} s simulated at 1 kHz), medians of {args.repeats} run(s)")
    for k, w in med.items():
        print(f"  {k:8s} {w:7.1f} s wall  {cfg.n_instances / w:6.2f} instances/s  {sim_seconds / w:6.1f} x real time")
    print(f"  ray start-up (ray.init, 2 CPUs)  {init:.1f} s")
    over = med["ray-2"] / med["local-2"] - 1
    over_init = (med["ray-2"] + init) / med["local-2"] - 1
    print(f"Ray overhead vs local processes: {100 * over:+.1f} % (running cluster), {100 * over_init:+.1f} % "
          f"(start-up included)   target < 15 %")
    print(f"1 -> 2 local workers speed-up: {med['local-1'] / med['local-2']:.2f}x; byte-identical across executors: {same}")
    load_after = os.getloadavg()[0]
    print(f"load average after: {load_after:.2f}")
    doc = {"scenario": args.scenario, "profile": "default", "n_instances": cfg.n_instances, "n_samples": samples,
           "repeats": args.repeats, "wall_s": walls, "median_wall_s": med, "ray_init_s": ray_init,
           "ray_overhead": over, "ray_overhead_with_startup": over_init, "byte_identical": same,
           "load_before": load_before, "load_after": load_after, "cpu_count": os.cpu_count()}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
