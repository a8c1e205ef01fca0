"""Dataset generation speed (issue 3).

Prints, measured in this one run:
  bare DART step      setForces + world.step with a Python loop, simulated s per wall s (context)
  sim loop + sensors  Simulator.run on a ready reference (controller, friction, pulses, DART, sensors)
  full instance       simulate_instance: planning + timing + the above, what a worker does
                      (medians over instances, one core)
  worker start        seconds to spawn one worker process and build its models
  1 -> 2 workers      generate_dataset end to end (process start included) with 1 and 2 workers,
                      wall time and speed-up; the two directories must be byte-identical.
Floors (issue 3): >= 10x real time per core at 1 kHz with sensors on; >= 1.7x from 1 to 2 workers.

Run: .venv/bin/python benchmarks/generation_speed.py [--instances 16] [--trajectories 10] [--repeats 2]
The machine's load average is printed first: the speed-up needs two otherwise idle cores.
"""
import argparse
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from hybrid_dyn.sim.executors import ProcessExecutor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.instances import _simulator_for, instance_rngs, simulate_instance
from hybrid_dyn.sim.simulator import Simulator
from hybrid_dyn.sim.plant import DartPlant
from hybrid_dyn.sim.pulses import sample_pulses
from hybrid_dyn.sim.scenarios import scenario_config
from hybrid_dyn.sim.trajectories import random_reference
from hybrid_dyn.timing import Stopwatch


def bare_dart_speed(sim: Simulator, steps: int = 1000, repeats: int = 10) -> float:
    """setForces + world.step under gravity compensation at home, reset every ``steps``
    (held longer, the unstable pose drifts and the arm falls, which is not a fair step)."""
    plant = DartPlant(sim.plant_robot, sim.config.dt)
    q = np.asarray(sim.plant_robot.spec.home, float)
    tau = sim.plant_robot.gravity(q)
    runs = []
    for _ in range(repeats):
        plant.set_state(q, np.zeros(7))
        with Stopwatch() as sw:
            for _ in range(steps):
                plant.skel.setForces(tau)
                plant.world.step()
        runs.append(steps * sim.config.dt / sw.wall)
    return float(np.median(runs))


def _build_simulator(config_json: str) -> int:
    return _simulator_for(config_json).nv


def worker_start_seconds(cfg) -> float:
    """Wall time to start one spawned worker: interpreter, imports, robots, collision model."""
    with Stopwatch() as sw:
        list(ProcessExecutor(1).map_unordered(_build_simulator, [(json.dumps(cfg.to_dict(), sort_keys=True),)]))
    return sw.wall


def tree_bytes(path: Path) -> dict:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", type=int, default=16)
    ap.add_argument("--trajectories", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    cfg = scenario_config("paper-ext", "quick", n_instances=args.instances,
                          trajectories=(args.trajectories, args.trajectories))
    sim = Simulator(cfg)

    print(f"bare DART step (Python loop)        {bare_dart_speed(sim):7.1f} x real time")

    loop, full, sim_seconds = [], [], 0.0
    for i in range(min(args.instances, 6)):
        rng_traj, rng_pulse, rng_noise = instance_rngs(cfg.seed, 1000 + i)
        ref = random_reference(sim.nominal, rng_traj, args.trajectories, dt=cfg.dt, speed_scale=cfg.speed_scale,
                               is_valid=sim.checker)
        force = sample_pulses(rng_pulse, cfg.pulses).force(ref.t)
        with Stopwatch() as sw:
            sim.run(ref.q, ref.qd, ref.qdd, force, rng_noise)
        loop.append(len(ref) * cfg.dt / sw.wall)
        with Stopwatch() as sw:
            run, _ = simulate_instance(sim, i)
        full.append(run.attrs["duration_s"] / sw.wall)
        sim_seconds += run.attrs["duration_s"]
    print(f"sim loop + sensors (1 kHz, 100 Hz)  {np.median(loop):7.1f} x real time per core")
    print(f"full instance (plan + sim + sensors){np.median(full):7.1f} x real time per core "
          f"(median of {len(full)}, {sim_seconds / len(full):.1f} s simulated each)   floor >= 10x")

    print(f"worker start (spawn, imports, models)  {worker_start_seconds(cfg):.1f} s")
    walls, cores = {1: [], 2: []}, {1: [], 2: []}
    same = True
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(args.repeats):  # alternate, so a burst of load elsewhere hits both
            for workers in (1, 2):
                out = Path(tmp) / f"r{rep}w{workers}"
                with Stopwatch() as sw:
                    generate_dataset(cfg, out, workers=workers, progress=False)
                walls[workers].append(sw.wall)
                cores[workers].append(sw.cores)
            same &= tree_bytes(Path(tmp) / f"r{rep}w1") == tree_bytes(Path(tmp) / f"r{rep}w2")
            for workers in (1, 2):
                shutil.rmtree(Path(tmp) / f"r{rep}w{workers}")
    w1, w2 = np.median(walls[1]), np.median(walls[2])
    print(f"generate {args.instances} instances x {args.trajectories} trajectories "
          f"({args.repeats} runs each, medians): 1 worker {w1:.1f} s, 2 workers {w2:.1f} s, "
          f"speed-up {w1 / w2:.2f}x   floor >= 1.7x; byte-identical: {same}")
    for w in (1, 2):
        print(f"  {w} worker(s): wall {[round(x, 1) for x in walls[w]]} s, CPU cores obtained "
              f"{[round(x, 2) for x in cores[w]]} (below {w}: other processes took the rest)")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
