"""Executors: run independent jobs (one per dataset instance) serially or in parallel.

An executor maps a picklable top-level function over argument tuples and
yields the results as they finish, in any order. The generator only relies on
``map_unordered``, so other back-ends (a Ray cluster, issue 9) plug in by
providing that one method.
"""
from __future__ import annotations

import multiprocessing as mp
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait


class SerialExecutor:
    """Runs the jobs one after another in this process."""

    workers = 1

    def map_unordered(self, fn, jobs):
        for args in jobs:
            yield fn(*args)


class ProcessExecutor:
    """Runs the jobs in ``workers`` local processes (spawned: no forked library state).

    At most ``2 * workers`` jobs are queued at a time, so an interrupt loses
    little queued work and memory stays flat for long runs.
    """

    def __init__(self, workers: int):
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.workers = workers

    def map_unordered(self, fn, jobs):
        jobs = iter(jobs)
        pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"))
        pending = set()
        try:
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
        finally:
            # On an interrupt or error: drop queued jobs; finished files stay on disk.
            pool.shutdown(wait=True, cancel_futures=True)


def make_executor(workers: int):
    return SerialExecutor() if workers == 1 else ProcessExecutor(workers)
