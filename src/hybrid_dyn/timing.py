"""One timer for every speed figure the toolkit and its benchmarks quote.

Each figure is one of four measurements, and each is taken here, the same way everywhere:

- :func:`time_calls`: single calls timed one by one (a control loop's view: latency, its median and
  tail). ``call(k)`` gets the call's index, so a stream can be fed in order; ``cpu=True`` also gives
  the CPU time of this thread in each call (a wall time far above it is the scheduler, not the call).
- :func:`median_call_us`: the median of ``n`` such calls after ``warmup`` untimed ones [us].
- :func:`per_item_us`: throughput of a batched call: the mean time of ``number`` calls, per item, the
  median over ``repeat`` runs [us per item].
- :func:`interleaved_rates`: several steps timed in turn within every repeat, so that load from other
  processes on a shared machine falls on all of them alike [items per second, medians].

:class:`Stopwatch` is the wall clock (and the CPU time of this process and its finished children) of
one block of work, such as generating a dataset.

Callers: the bench's per-row single call (``bench/scoring.py``), the streaming runtime's choice
(``learn/stream_predictor.py``), the training throughput (``learn/speed.py``) and ``benchmarks/*.py``.
"""
from __future__ import annotations

import time

import numpy as np


def time_calls(call, ks, cpu: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """Call ``call(k)`` for every ``k`` of ``ks`` in order, each timed alone. Returns the wall time of
    each call [s] and, with ``cpu``, the CPU time this thread spent in each [s] (else None)."""
    ks = list(ks)
    wall = np.empty(len(ks))
    used = np.empty(len(ks)) if cpu else None
    for i, k in enumerate(ks):
        c0 = time.thread_time() if cpu else 0.0
        t0 = time.perf_counter()
        call(k)
        wall[i] = time.perf_counter() - t0
        if cpu:
            used[i] = time.thread_time() - c0
    return wall, used


def median_call_us(call, n: int, warmup: int = 50) -> float:
    """Median time of one call of ``call()`` [us]: ``warmup`` untimed calls, then ``n`` timed one by one."""
    if n < 1:
        raise ValueError(f"time at least one call, got n={n}")
    for _ in range(warmup):
        call()
    wall, _ = time_calls(lambda _k: call(), range(n))
    return float(np.median(wall) * 1e6)


def per_item_us(call, per: int = 1, repeat: int = 7, number: int = 200) -> float:
    """Time per item of a call that handles ``per`` items [us]: the mean over ``number`` calls in a row,
    the median over ``repeat`` such runs (no warm-up: give one, or call it once first)."""
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            call()
        runs.append((time.perf_counter() - t0) / number / per * 1e6)
    return float(np.median(runs))


def interleaved_rates(steps_and_sizes: list, n_steps: int, repeats: int, warmup: int = 3) -> list[float]:
    """Median items per second of each ``(step, items per step)``: every step warmed up ``warmup`` times,
    then, in each of ``repeats`` rounds, each step run ``n_steps`` times in turn, so that load from other
    processes on a shared machine falls on all of them alike."""
    for step, _ in steps_and_sizes:
        for _ in range(warmup):
            step()
    rates = [[] for _ in steps_and_sizes]
    for _ in range(repeats):
        for (step, size), out in zip(steps_and_sizes, rates):
            t0 = time.perf_counter()
            for _ in range(n_steps):
                step()
            out.append(n_steps * size / (time.perf_counter() - t0))
    return [float(np.median(r)) for r in rates]


def cpu_seconds() -> float:
    """CPU time of this process and of its finished children (worker processes), user + system [s]."""
    import resource  # POSIX only: imported where it is needed

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


class Stopwatch:
    """``with Stopwatch() as sw: ...`` then ``sw.wall`` [s] and ``sw.cpu`` [s, this process and its finished
    children]; ``sw.cores`` = cpu / wall, the cores the block obtained."""

    def __enter__(self):
        self.wall = self.cpu = float("nan")
        self._c0 = cpu_seconds()
        self._t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self._t0
        self.cpu = cpu_seconds() - self._c0
        return False

    @property
    def cores(self) -> float:
        return self.cpu / self.wall if self.wall > 0 else float("nan")
