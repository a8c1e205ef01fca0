"""A bench report folder's record, written here and only here while the bench runs: the folder claimed (or
refused when it is not the bench's), each invocation's wall and CPU time in run.json as it goes (a heartbeat
while it generates or trains), results.csv and curves.json after every row, at the end run.json with the
digest that vouches for results.csv, and the files the report draws (``report.py`` calls
:func:`record_report_files`). ``integrity.py`` computes and checks the digests; ``results.py`` is the files' format.

A bench may take several invocations (it resumes from its caches), and one of them may be killed by the user or
by the OOM killer; the report adds up the parts that run.json recorded (``report._invocation_times``), and
``checks/acceptance.py`` reads a wall time "from empty caches" only where the first invocation says it began on
empty caches (:func:`caches_empty`).
"""
from __future__ import annotations

import contextlib
import dataclasses
import os
import threading
import time
from pathlib import Path

from ..data.logs.real_logs import REAL_SETS
from ..data.splits import dataset_split_text
from ..outputs import refuse_foreign
from ..timing import cpu_seconds
from .integrity import (DIGEST_KEY, REPORT_FILES, RUN_FILE, is_bench_meta, is_plain_name, read_run_json,
                        results_digest, run_digest, same_profile)
from .predictions import PREDICTIONS_FILE
from .plan import BenchPlan, is_dataset_path
from .profiles import BenchProfile
from .results import CURVES_FILE, write_curves, write_json, write_results
from .reference_study import REFERENCE_COMPARISON_FILE


def claim_report_dir(out_dir: Path, profile: BenchProfile, log=print) -> list[dict]:
    """Make ``out_dir`` a report folder of this toolkit, or refuse; returns its earlier invocations
    of the same profile (a report of another profile or size is being replaced: its wall times are
    of other work and are not kept).

    A folder is the bench's when its ``run.json`` carries the marker the bench wrote
    (``integrity.read_run_json``: ``"bench_report": 1`` and a recorded profile; a user's run.json
    with a ``profile`` key is not one); an empty or new folder is claimed by writing that marker before
    anything else, so a run killed halfway still leaves a folder a rerun may
    use. Anything else (a user's README.md or results.csv) is refused, named.
    """
    from ..errors import OutputPathError

    if out_dir.exists() and not out_dir.is_dir():
        raise OutputPathError(f"report folder {out_dir} exists and is not a directory")
    marker = out_dir / "run.json"
    claim = {"bench_report": 1, "invocations": [], "profile": profile.to_dict()}  # the marker, no invocation yet
    old = read_run_json(out_dir)  # refuses a run.json the bench did not write
    if old is not None:
        if not same_profile(old["profile"], profile):  # an old recipe name or corrected notes: the same profile
            log(f"[bench] {out_dir} held a report of another profile or size: it is replaced, and its "
                "invocations' wall times are not kept")
            take_over(out_dir, old, claim)
            return []
        if "invocations" in old:
            return list(old["invocations"])
        return [{"wall_seconds": old.get("wall_seconds")}]  # a report from before invocations were kept
    present = sorted(p.name for p in out_dir.iterdir()) if out_dir.is_dir() else []
    if present:
        refuse_foreign(out_dir, "benchmark report",
                       f"it holds {', '.join(present[:5])}{' ...' if len(present) > 5 else ''} but no run.json")
    out_dir.mkdir(parents=True, exist_ok=True)
    # The profile now, not only at the end: the report of an interrupted bench (``hybrid-dyn report``)
    # still says what was run, and with which recipe.
    write_json(marker, claim)
    return []


# What a bench report of any profile holds beside run.json, whatever its run.json records: the bench's files
# and the report's fixed names (a report written before run.json recorded its files names no figure).
BENCH_FILES = ("results.csv", CURVES_FILE, PREDICTIONS_FILE, "README.md", "tip_force.md", "tip_force.tex",
               "joint_torque.md", "joint_torque.tex", REFERENCE_COMPARISON_FILE)


def take_over(out_dir: Path, old: dict, claim: dict) -> None:
    """Replace another profile's report in ``out_dir`` (``old``: its run.json) by this bench's ``claim``, in one
    step: its outputs (:data:`BENCH_FILES` and the files its run.json records) are removed first, then the
    claim is written. A kill in between leaves the old run.json over fewer of its files (a rerun takes over
    again), never the new run.json beside the other profile's README, tables or figures."""
    remove_report_files(out_dir, [*BENCH_FILES, *(old.get(REPORT_FILES) or [])])
    # Empty results.csv and curves.json, and the claim vouching for them: until this bench's first row the
    # folder is a report of no row (and says so), never the other profile's.
    write_results(out_dir / "results.csv", [])
    write_curves(out_dir / CURVES_FILE, [])
    write_json(out_dir / "run.json", {**claim, DIGEST_KEY: results_digest(out_dir / "results.csv", claim)})


def _utc_now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


@dataclasses.dataclass
class InvocationClock:
    """This invocation's entry in run.json's ``invocations``, kept current as the bench goes.

    A bench that spans sittings is several invocations, and one of them may be killed (by the user,
    or by the OOM killer, which no handler sees): run.json gets its wall time so far as each dataset
    and row finishes and, while it generates or trains, every :attr:`period` seconds (a heartbeat),
    so the next invocation keeps it (``"finished": null`` says it did not finish) and the report
    adds the parts up. ``previous``: the earlier invocations, read when the folder was claimed.
    ``cold_start``: whether this profile's datasets and trained models were absent when it began
    (:func:`caches_empty`): a wall time "from empty caches" is one whose first invocation was cold."""

    previous: list
    cold_start: bool = False
    period: float = 60.0
    # Recorded from the start, so the report of a killed bench names the rows that never ran: every
    # requested row (``integrity.row_key``), and those found not to apply so far (the bench appends).
    requested: list = dataclasses.field(default_factory=list)
    skipped: list = dataclasses.field(default_factory=list)
    started: str = dataclasses.field(default_factory=_utc_now)
    t0: float = dataclasses.field(default_factory=time.perf_counter)
    cpu0: float = dataclasses.field(default_factory=cpu_seconds)
    # Where this invocation's time went: phase name -> wall and CPU seconds (:meth:`phase`).
    phases: dict = dataclasses.field(default_factory=dict)
    _lock: object = dataclasses.field(default_factory=threading.Lock, repr=False)

    def seconds(self) -> float:
        return time.perf_counter() - self.t0

    def cpu_used(self) -> float:
        """CPU time [s] of this invocation so far: its process and its finished worker processes (a worker
        still running is counted when it ends: training pools end with each scenario's training)."""
        return cpu_seconds() - self.cpu0

    def invocations(self, rows: list, finished: bool) -> list:
        return self.previous + [{"started": self.started, "finished": _utc_now() if finished else None,
                                 "wall_seconds": self.seconds(), "cpu_seconds": self.cpu_used(),
                                 "cold_start": self.cold_start,
                                 "rows": len(rows), "rows_ok": sum(r.get("status") == "ok" for r in rows),
                                 "phases": {k: dict(v) for k, v in self.phases.items()}}]

    @contextlib.contextmanager
    def phase(self, name: str):
        """Add the body's wall and CPU seconds (this process and the workers that ended in it) to phase
        ``name``: the profile of the invocation (generation, training, scoring) that the report prints."""
        t0, c0 = time.perf_counter(), cpu_seconds()
        try:
            yield
        finally:
            with self._lock:
                p = self.phases.setdefault(name, {"wall_seconds": 0.0, "cpu_seconds": 0.0})
                p["wall_seconds"] += time.perf_counter() - t0
                p["cpu_seconds"] += cpu_seconds() - c0

    def record(self, out_dir: Path, rows: list, rows_written: bool = True) -> None:
        """run.json with this invocation's time so far. ``rows_written``: results.csv now holds ``rows``
        (written by this invocation), so the digest vouches for it as it is; otherwise the digest keeps
        what it vouched for (results.csv's sha256 and rows) and only its run.json part follows the new
        time: rows this invocation has not computed are never vouched for anew (a hand edit stays caught)."""
        with self._lock:
            meta = read_run_json(out_dir)
            meta["invocations"] = self.invocations(rows, finished=False)
            meta["requested"], meta["skipped"] = self.requested, list(self.skipped)
            old = meta.pop(DIGEST_KEY, None)
            if rows and rows_written:
                meta[DIGEST_KEY] = results_digest(out_dir / "results.csv", meta)
            elif old is not None:
                meta[DIGEST_KEY] = {**old, "run": run_digest(meta)}
            write_json(out_dir / "run.json", meta)

    @contextlib.contextmanager
    def heartbeat(self, out_dir: Path, rows: list):
        """Record every :attr:`period` seconds while the body runs (hours of generation or training
        write nothing else), and once more if the body is interrupted (Ctrl-C: its time is kept)."""
        stop = threading.Event()

        def beat():
            while not stop.wait(self.period):
                self.record(out_dir, rows, rows_written=False)

        thread = threading.Thread(target=beat, name="bench-heartbeat", daemon=True)
        thread.start()
        finished = False
        try:
            yield
            finished = True
        finally:
            stop.set()
            thread.join()
            if not finished:
                self.record(out_dir, rows, rows_written=False)


def caches_empty(profile: BenchProfile, data_root: Path, work_root: Path) -> bool:
    """Whether none of the profile's simulated datasets and none of its trained models exist yet (the
    real logs' imports are cheap and not counted; a dataset path given by the user is not the bench's)."""
    if (Path(work_root) / profile.name).exists():
        return False
    plan = BenchPlan(profile)
    return not any(plan.dataset_path(s, data_root).exists() for s in profile.scenarios
                   if not is_dataset_path(s) and s not in REAL_SETS)


def record_row(out_dir: Path, rows: list, clock: InvocationClock) -> None:
    """A row just finished (appended to ``rows``): results.csv, run.json's invocation and digest, curves.json."""
    write_results(out_dir / "results.csv", rows)
    clock.record(out_dir, rows)
    write_curves(out_dir / CURVES_FILE, rows)


def finish_record(out_dir: Path, rows: list, meta: dict) -> None:
    """The run's end: results.csv (also when no row applied: the report reads it), and run.json (``meta``, from
    :func:`run_meta`) with the digest ``hybrid-dyn report`` checks against. The files an earlier report drew
    here stay on record (this report removes those it no longer draws)."""
    meta[REPORT_FILES] = read_run_json(out_dir).get(REPORT_FILES) or []
    write_results(out_dir / "results.csv", rows)
    meta[DIGEST_KEY] = results_digest(out_dir / "results.csv", meta)
    write_json(out_dir / "run.json", meta)


def import_warnings(ds) -> list[str]:
    """The warnings an import recorded in the dataset's manifest (they once never reached the report,
    which then showed RNEA off by 0.55 Nm on a log whose time unit the import had said did not fit)."""
    imp = ds.meta.get("import")
    warnings = imp.get("warnings") if isinstance(imp, dict) else None
    return [str(w) for w in warnings] if isinstance(warnings, list) else []


def recorded_path(path) -> str:
    """A dataset's path as run.json and the README record it: relative to the working directory, so that a
    committed report names no folder of the machine that wrote it (an absolute path given on the command
    line, ``--data-root /work/x/data``, is recorded as ``data/...`` when run from ``/work/x``)."""
    path = Path(path)
    if not path.is_absolute():
        return str(path)
    try:
        return os.path.relpath(path)
    except ValueError:  # another drive (Windows): no relative path exists
        return str(path)


def run_meta(profile: BenchProfile, clock: InvocationClock, rows: list, labels: dict, skipped: list,
             datasets: dict, dataset_seconds: dict, machine: dict) -> dict:
    """run.json (before its digest): the profile, every invocation's wall time, the scenarios and rows not run,
    the machine and each dataset."""
    # Keep every invocation (``clock.previous``, read when the folder was claimed): a rerun
    # that reuses cached data and models is fast, and the first, full run's wall
    # time must not be overwritten by it.
    invocations = clock.invocations(rows, finished=True)
    wall = invocations[-1]["wall_seconds"]
    return {"bench_report": 1, "profile": profile.to_dict(), "wall_seconds": wall, "invocations": invocations,
            "scenarios": labels, "requested": clock.requested, "skipped": skipped, "machine": machine,
            "datasets": {s: {"path": recorded_path(d.path), "checksum": d.checksum, "seed": d.meta.get("seed"),
                             "config_hash": d.meta.get("config_hash"), "robot": d.meta.get("robot"),
                             "split": dataset_split_text(d), "dataset_seconds": dataset_seconds.get(s),
                             **({"import_warnings": import_warnings(d)} if import_warnings(d) else {})}
                         for s, d in datasets.items()}}


def record_report_files(out_dir, meta: dict, files) -> None:
    """Record in the folder's run.json (``meta``, as on disk and checked) the files the report wrote there, and
    vouch for run.json anew with them (its digest's run part); no run.json of the bench's there: nothing."""
    out_dir = Path(out_dir)
    if not (out_dir / RUN_FILE).is_file() or not is_bench_meta(meta):
        return
    meta = {**meta, REPORT_FILES: sorted(set(files))}
    if isinstance(meta.get(DIGEST_KEY), dict):
        meta[DIGEST_KEY] = {**meta[DIGEST_KEY], "run": run_digest(meta)}
    write_json(out_dir / RUN_FILE, meta)


def remove_report_files(out_dir, names) -> None:
    """Remove the report's files ``names`` (recorded in run.json: the only files ever removed by name) from
    ``out_dir``; a name already gone is skipped."""
    for name in names:
        path = Path(out_dir) / name
        if is_plain_name(name) and (path.is_file() or path.is_symlink()):
            path.unlink()
