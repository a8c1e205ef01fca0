"""The bench's training jobs on a Ray cluster: the same model files as the local pool, byte for byte."""
import dataclasses

import pytest

from hybrid_dyn.bench.profiles import PROFILES
from hybrid_dyn.bench.runner import run_bench
from hybrid_dyn.errors import UsageError
from hybrid_dyn.sim.executors import ProcessExecutor, RayExecutor

ROWS = ("seed-tip-1", "seed-tau-mlp")  # two learned rows, one per task


def tiny_profile():
    return dataclasses.replace(
        PROFILES["quick"], name="tiny", families=(), rows=ROWS,
        generator_overrides=dict(n_instances=3, trajectories=(1, 1)), scenario_overrides={},
        train=dict(budget_steps=3, budget_evals=1, batch_size=64), workers=2)


def model_bytes(work_root):
    """Every file of every trained model under a bench work root but ``timing.json`` (wall seconds)."""
    files = sorted(p for p in work_root.rglob("models/*/*") if p.is_file() and p.name != "timing.json")
    return {str(p.relative_to(work_root)): p.read_bytes() for p in files}


@pytest.mark.slow
def test_ray_training_jobs_write_the_local_pools_bytes(tmp_path):
    data = tmp_path / "data"
    local = run_bench(tiny_profile(), tmp_path / "local", data_root=data, work_root=tmp_path / "runs-local",
                      executor=ProcessExecutor(2), log=lambda m: None)
    on_ray = RayExecutor(workers=2)  # a local Ray instance, started and stopped by the executor
    remote = run_bench(tiny_profile(), tmp_path / "ray", data_root=data, work_root=tmp_path / "runs-ray",
                       executor=on_ray, log=lambda m: None)
    assert on_ray.workers == 2  # the CPUs Ray reported: the jobs ran on Ray
    a, b = model_bytes(tmp_path / "runs-local"), model_bytes(tmp_path / "runs-ray")
    assert {k.split("/")[-2] for k in a} == set(ROWS)  # both rows trained, model and config files
    assert a.keys() == b.keys() and a == b
    assert [r["status"] for r in local] == [r["status"] for r in remote] == ["ok"] * len(local)
    assert [r["rmse"] for r in local] == [r["rmse"] for r in remote]


def test_gpus_per_job_needs_a_ray_executor(tmp_path):
    with pytest.raises(UsageError, match="--executor ray"):
        run_bench(tiny_profile(), tmp_path / "r", data_root=tmp_path / "d", work_root=tmp_path / "w",
                  executor=ProcessExecutor(2), gpus_per_job=0.5)


@pytest.mark.slow  # two small benches, the second with a worker process
def test_the_identified_residual_nets_train_in_a_worker_to_the_serial_runs_bytes(panda_log, tmp_path):
    """With 2 workers the residual nets on the identified model train in a worker process while
    the bench's process fits and scores the rest; the model files and the rows are those of one process."""
    from hybrid_dyn.bench.profiles import profile_for_data
    from hybrid_dyn.bench.results import SCORED_STATUSES

    def bench(workers, name):
        messages = []
        profile = profile_for_data([panda_log], families=(), workers=workers,
                                   rows=("identified-consistent", "residual-rnea-identified", "identified-ols",
                                         "gp-residual-identified"),
                                   train=dict(budget_steps=3, budget_evals=1, batch_size=64, progress=False))
        # One work root for both (the model's config names its prior's file there), kept aside after each run.
        rows = run_bench(profile, tmp_path / f"report-{name}", data_root=tmp_path / "data",
                         work_root=tmp_path / "runs", log=messages.append)
        (tmp_path / "runs").rename(tmp_path / f"runs-{name}")
        return rows, messages

    serial, _ = bench(1, "serial")
    parallel, said = bench(2, "parallel")
    assert any("residual-rnea-identified" in m and "in a worker" in m for m in said), said
    # Scored rows (an identified row on this small log may be "implausible"), as the serial run's.
    assert [r["status"] for r in parallel] == [r["status"] for r in serial]
    assert all(r["status"] in SCORED_STATUSES for r in parallel), [r["status"] for r in parallel]
    a, b = model_bytes(tmp_path / "runs-serial"), model_bytes(tmp_path / "runs-parallel")
    assert len(a) >= 2 and a == b
    assert [(r["model"], r["rmse"]) for r in serial] == [(r["model"], r["rmse"]) for r in parallel]
    # The identification's CPU goes to the first row that reads it, though it ran before any row was scored.
    row = next(r for r in parallel if r["model"] == "identified-consistent")
    assert row["train_cpu_seconds"] > 0
