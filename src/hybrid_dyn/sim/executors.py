"""Executors: run independent jobs (one per dataset instance) serially, in local processes, or on Ray.

An executor maps a picklable top-level function over argument tuples and
yields the results as they finish, in any order. The generator only relies on
``map_unordered``, so a back-end is that one method:

- ``SerialExecutor``: this process (tests, debugging);
- ``ProcessExecutor``: local processes, the default;
- ``RayExecutor``: tasks on a Ray cluster (``pip install hybrid-dyn[cluster]``).
  Ray schedules them, retries a task whose worker died, and runs them on any
  machine of the cluster; the jobs write their results to a store all
  machines reach (``data/store.py``), so only small records travel back.

Each job is deterministic in its arguments, so the bytes of a dataset do not
depend on the executor, the worker count or the order in which jobs finish.

Local worker processes die with the process that started them (``process_pool``):
a parent killed with SIGKILL runs no cleanup, and its workers would otherwise live
on, idle, at a few hundred MB each, with the multiprocessing resource tracker.
"""
from __future__ import annotations

import contextlib
import ctypes
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from ..errors import MissingDependencyError, UsageError

PR_SET_PDEATHSIG = 1  # linux/prctl.h
WATCHDOG_PERIOD_S = 0.5


def _set_parent_death_signal(sig: int) -> bool:
    """Linux: ask the kernel to send ``sig`` to this process when its parent dies. False elsewhere."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        return ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch_parent(parent_pid: int) -> None:
    """Exit as soon as the parent is gone (this process was re-parented): the portable guard."""
    while os.getppid() == parent_pid:
        time.sleep(WATCHDOG_PERIOD_S)
    os._exit(1)


def _worker_init(parent_pid: int) -> None:
    """Initializer of every local worker: die with the parent, leave Ctrl-C to it.

    SIGKILL on the parent's death (Linux; the kernel sends it even when the parent was
    SIGKILLed), a watchdog thread on any system, and a check for a parent that died
    before either was in place. SIGINT is ignored: a terminal's Ctrl-C reaches the whole
    process group, and the parent stops the workers itself (``process_pool``).
    """
    _set_parent_death_signal(signal.SIGKILL)
    if os.getppid() != parent_pid:
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid,), name="parent-watchdog", daemon=True).start()
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextlib.contextmanager
def process_pool(workers: int):
    """A ``ProcessPoolExecutor`` of ``workers`` spawned processes (no forked library state) that die with this one.

    On normal exit the pool is shut down as usual. On an interrupt (Ctrl-C, SIGTERM via the
    CLI), an error or an abandoned generator, queued jobs are dropped and the running
    workers are stopped (SIGTERM), not waited for: their results would not be collected,
    and every job here writes atomically, so a stopped job leaves only a temporary that
    the next run removes. The pool must be used from the thread that created it (the
    parent-death signal follows the creating thread).
    """
    pool = ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"), initializer=_worker_init,
                               initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in processes:
            if proc.is_alive():
                proc.terminate()
        for proc in processes:
            proc.join(timeout=10)
        pool.shutdown(wait=True)  # joins the pool's manager thread
        raise
    else:
        pool.shutdown(wait=True)


class SerialExecutor:
    """Runs the jobs one after another in this process."""

    workers = 1

    def map_unordered(self, fn, jobs):
        for args in jobs:
            yield fn(*args)


class ProcessExecutor:
    """Runs the jobs in ``workers`` local processes (``process_pool``: spawned, and they die with this one).

    At most ``2 * workers`` jobs are queued at a time, so an interrupt loses
    little queued work and memory stays flat for long runs.
    """

    def __init__(self, workers: int):
        if workers < 1:
            raise UsageError(f"workers must be >= 1, got {workers}")
        self.workers = workers

    def map_unordered(self, fn, jobs):
        jobs = iter(jobs)
        pending = set()
        # On an interrupt or error: queued jobs are dropped; finished files stay on disk.
        with process_pool(self.workers) as pool:
            for args in jobs:
                pending.add(pool.submit(fn, *args))
                if len(pending) >= 2 * self.workers:
                    break
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    yield fut.result()
                    nxt = next(jobs, None)
                    if nxt is not None:
                        pending.add(pool.submit(fn, *nxt))


class RayExecutor:
    """Runs the jobs as Ray tasks, one CPU each.

    address: a running cluster ("auto", "ray://head:10001", "head:6379"), or
    None to start a local Ray instance with ``workers`` CPUs (this machine).
    If Ray is already initialised in this process, that instance is used.
    At most ``2 x (cluster CPUs)`` tasks are in flight, as for local processes.
    gpus_per_task: GPUs each task reserves (fractions share one: a study net uses a
    sliver of a GPU); 0 for CPU jobs. Ray hides the GPUs from a task that reserved none.
    """

    def __init__(self, workers: int | None = None, address: str | None = None, gpus_per_task: float = 0.0):
        try:
            import ray  # noqa: F401
        except ImportError as err:
            raise MissingDependencyError("the ray executor needs Ray: pip install 'hybrid-dyn[cluster]'") from err
        if workers is not None and workers < 1:
            raise UsageError(f"workers must be >= 1, got {workers}")
        if not gpus_per_task >= 0:
            raise UsageError(f"GPUs per task must be >= 0, got {gpus_per_task}")
        self.address = address
        self.requested_workers = workers
        self.workers = workers or 1
        self.gpus_per_task = float(gpus_per_task)

    def with_gpus(self, gpus_per_task: float) -> "RayExecutor":
        """The same cluster, its tasks each reserving ``gpus_per_task`` GPUs (the training jobs on GPU nodes)."""
        return RayExecutor(self.requested_workers, self.address, gpus_per_task)

    def _connect(self) -> bool:
        """Initialise Ray if needed; True when this executor started it (and must shut it down)."""
        import ray

        if ray.is_initialized():
            return False
        opts = dict(include_dashboard=False, log_to_driver=False, logging_level="ERROR")
        if self.address:
            ray.init(address=self.address, **opts)
        else:  # a local instance: no more CPUs than asked for, a small object store (records are tiny)
            ray.init(num_cpus=self.requested_workers or os.cpu_count(), object_store_memory=100 * 2**20, **opts)
        return True

    def map_unordered(self, fn, jobs):
        import ray

        started = self._connect()
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        # A task whose worker died is rerun.
        task = ray.remote(num_cpus=1, num_gpus=self.gpus_per_task, max_retries=3)(fn)
        jobs = iter(jobs)
        pending = []
        try:
            for args in jobs:
                pending.append(task.remote(*args))
                if len(pending) >= 2 * self.workers:
                    break
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                yield ray.get(done[0])
                nxt = next(jobs, None)
                if nxt is not None:
                    pending.append(task.remote(*nxt))
        finally:
            # On an interrupt or error: cancel what is queued; finished files stay in the store.
            for ref in pending:
                ray.cancel(ref, force=True)
            if started:
                ray.shutdown()


EXECUTORS = ("local", "ray")


def make_executor(workers: int, kind: str = "local", address: str | None = None):
    """The executor for ``--executor``: "local" (processes; serial for one worker) or "ray"."""
    if kind == "local":
        if address:
            raise UsageError("--ray-address needs --executor ray")
        return SerialExecutor() if workers == 1 else ProcessExecutor(workers)
    if kind == "ray":
        return RayExecutor(workers, address)
    raise UsageError(f"executor must be one of {EXECUTORS}, got {kind!r}")
