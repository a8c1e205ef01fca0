"""Folder snapshots, and a dataset generation that runs in a child process and pauses inside its run."""
from __future__ import annotations

from pathlib import Path


def dir_bytes(path) -> dict:
    """Every file of a folder: relative name -> bytes."""
    path = Path(path)
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


class PausingExecutor:
    """Serial executor that signals it is inside the run, then waits for the test's go."""

    def __init__(self, started, go):
        self.started, self.go = started, go

    def map_unordered(self, fn, jobs):
        from hybrid_dyn.sim.executors import SerialExecutor

        self.started.set()
        assert self.go.wait(120), "the test never said go"
        yield from SerialExecutor().map_unordered(fn, jobs)


def generate_in_child(config, out, started, go, result):
    """``generate_dataset(config, out)`` through a PausingExecutor; puts "ok" or the error on ``result``.
    Here, not in a test module, so that a spawned process can import it (``helpers`` is on its path)."""
    from hybrid_dyn.sim.generator import generate_dataset

    try:
        generate_dataset(config, out, progress=False, executor=PausingExecutor(started, go), log=lambda m: None)
        result.put("ok")
    except BaseException as err:  # report anything to the parent
        result.put(f"{type(err).__name__}: {err}")
