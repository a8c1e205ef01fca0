"""The benchmark harness: every model family on the same data, one results table (``run_bench``).

For each scenario of a profile: make (or reuse) the dataset, then for each model row build a predictor (analytic
rows: nothing to train; learned rows: train or reuse, ``training_queue.py``), predict every sample of the
validation and test splits and score all rows alike (``scoring.py``). A row that fails is written with its error,
not dropped. The rows are those of the registry (``rows.py``) that the profile names and that apply to the
dataset (``BenchPlan.skip_reason``); each that does not is logged and listed in run.json and the README with its
reason. A scenario is a simulated or real set's name, or any dataset's path (``hybrid-dyn bench --data``).

Files, each written atomically as rows finish (an interrupted bench keeps them): results.csv, curves.json and
run.json (``run_record.py``), predictions.h5 (``predictions.py``). The report is then drawn from those files
alone (``report.write_report``), as ``hybrid-dyn report`` redraws it.
"""
from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import threading
import time
import traceback
from pathlib import Path
from typing import Callable

from tqdm.auto import tqdm

from ..analytic.robot import load_robot
from ..data import Dataset
from ..data.logs.real_logs import RealLogMissingError
from ..errors import UsageError
from ..outputs import output_lock
from .integrity import row_key
from ..learn.presets import PRESETS
from .predictions import PREDICTIONS_FILE, PredictionWriter
from .plan import BenchContext, BenchPlan, is_dataset_path, scenario_label
from .profiles import BenchProfile
from .report import machine_info, write_report
from .results import SCORED_STATUSES, read_results
from .rows import TASK_TARGET
from .run_record import (InvocationClock, caches_empty, claim_report_dir, finish_record, import_warnings,
                         record_row, run_meta)
from .scoring import score_row, train_split_stats
from .training_queue import pretrain, set_torch_threads


def default_work_root(work_root=None) -> Path:
    """The trained-model cache: ``work_root``, else ``$HYBRID_DYN_RUNS``, else ./runs."""
    return Path(work_root or os.environ.get("HYBRID_DYN_RUNS", "runs"))


def run_bench(profile: BenchProfile, out_dir, data_root=None, work_root=None, dataset_provider=None,
              log: Callable[[str], None] = print, executor=None, device: str | None = None,
              gpus_per_job: float = 0.0) -> list[dict]:
    """Run every row of ``profile`` on every scenario; write ``out_dir/results.csv`` and the report.

    dataset_provider(scenario, profile) -> Dataset; default: generate with the
    DART generator, cached by config hash under ``data_root``.
    Models and datasets are reused on rerun (same config and data checksum),
    so an interrupted bench resumes where it stopped. ``out_dir`` must be new,
    empty or an earlier report of the bench (its ``run.json``); it is locked
    for the run.

    executor: where generation and training jobs run (``sim/executors.make_executor``:
    local processes of ``profile.workers``, or Ray); device: the training device
    ("cpu", "cuda", ...; None: the profile's); gpus_per_job: GPUs each training job reserves
    on a Ray cluster (fractions share a GPU). None of them is part of the profile: they
    change where a job runs, not what it computes (on CPU, not a byte of it).
    """
    train_executor = executor
    if gpus_per_job:
        from ..sim.executors import RayExecutor

        if not isinstance(executor, RayExecutor):
            raise UsageError("GPUs per training job (--gpus-per-job) are reserved on a Ray cluster: "
                             "give --executor ray (a local run uses the GPU --device names)")
        train_executor = executor.with_gpus(gpus_per_job)
    # The study's networks are tiny: torch's intra-op threads cost more than they
    # give, and on a busy machine they spin (measured: a 2x32 MLP step 0.8 ms on
    # one thread, 118 ms on two with the cores oversubscribed). The bench owns its
    # process, so it pins torch to ``profile.torch_threads``.
    set_torch_threads(profile.torch_threads)
    plan = BenchPlan(profile)  # what this run does with the profile: datasets, robots, rows, training
    out_dir = Path(out_dir)
    data_root = Path(data_root or os.environ.get("HYBRID_DYN_DATA", "data"))
    work_root = default_work_root(work_root)
    provider = dataset_provider or (lambda scenario, prof: BenchPlan(prof).dataset(scenario, data_root, log=log,
                                                                                    executor=executor))
    # A missing or corrupt dataset, an unknown robot: refused before the report folder is touched.
    opened = _open_datasets(plan, provider, log)
    with output_lock(out_dir, "report folder"):  # one bench per report folder at a time
        cold = caches_empty(profile, data_root, work_root)
        previous = claim_report_dir(out_dir, profile, log)
        requested = [row_key({"scenario": label, "task": r.task, "model": r.name})
                     for _, label, _, _ in opened for r in plan.selected_rows()]
        clock = InvocationClock(previous, cold_start=cold, requested=requested)
        clock.record(out_dir, [], rows_written=False)  # on record before any work: a kill -9 leaves it unfinished
        # With workers, this process's BLAS on one thread: the workers hold the other cores, and BLAS threads
        # beside them spin against each other (CPU-seconds spent on nothing).
        with _blas_threads(1 if profile.workers > 1 else None):
            return _run_bench_locked(plan, out_dir, clock, data_root, work_root, provider, opened, log,
                                     train_executor, device)


@contextlib.contextmanager
def _blas_threads(n: int | None):
    """Every BLAS library of this process on ``n`` threads for the duration (None: as they are)."""
    if n is None:
        yield
        return
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=n, user_api="blas"):
        yield


def work_dir(plan: BenchPlan | BenchProfile, scenario: str, ds: Dataset, work_root: Path) -> Path:
    """Where a profile's models of one scenario are cached: one folder per dataset and training
    recipe, so a run with another recipe never meets these models. Takes the plan, or the profile it plans."""
    plan = plan if isinstance(plan, BenchPlan) else BenchPlan(plan)
    profile = plan.profile
    recipe = hashlib.sha256(json.dumps(plan.train_config().fingerprint_fields(), sort_keys=True).encode())
    name = f"{ds.checksum[:12]}-train-{recipe.hexdigest()[:8]}"
    if profile.robot is not None or profile.tool is not None:  # another analytic model: never its models
        robot = hashlib.sha256(str(ds.meta.get("robot")).encode()).hexdigest()[:8]
        name += f"-robot-{robot}"
    return Path(work_root) / profile.name / scenario / name


def _open_datasets(plan: BenchPlan, provider, log) -> list:
    """The profile's datasets as (entry, label, dataset or None, robot ref or skip reason), before any work
    where that is cheap: a dataset path is read and its robot resolved now (an unknown robot, a duplicate
    label fail here); a named scenario is made when its turn comes (None here)."""
    from .preflight import check_dataset, check_rows_apply

    out, seen = [], {}
    for entry in plan.profile.scenarios:
        ds = label = ref = None
        if is_dataset_path(entry):
            ds = provider(entry, plan.profile)
            label = scenario_label(entry, ds)
            ref = plan.robot_ref(ds)  # description.resolve_robot: the one check of a robot name
            check_dataset(plan.profile, label, ds, ref)  # splits, joint count, parameter set
        else:
            label = entry
        if label in seen:
            raise UsageError(f"datasets {seen[label]} and {entry} have the same scenario label {label!r} (their "
                             "manifests' 'scenario', or folder names): results.csv could not tell them apart")
        seen[label] = entry
        out.append((entry, label, ds, ref))
    if all(ds is not None for _, _, ds, _ in out):  # every dataset known now: some row must apply
        check_rows_apply(plan, [(label, ds) for _, label, ds, _ in out])
    return out


def _run_bench_locked(plan: BenchPlan, out_dir, clock: InvocationClock, data_root, work_root, provider, opened, log,
                      executor=None, device=None) -> list[dict]:
    profile = plan.profile
    rows: list[dict] = []
    skipped = clock.skipped  # on record in run.json as it grows
    datasets = {}
    labels = {}
    dataset_seconds = {}
    predictions = PredictionWriter(out_dir / PREDICTIONS_FILE, resume=bool(clock.previous))
    with clock.heartbeat(out_dir, rows):  # hours of generation or training are on record as they pass
        # Every dataset first, then every scenario's learned rows in one training queue, then the scoring:
        # one queue has one tail, where a queue per scenario left a core idle at each scenario's end.
        scenarios = []  # (context, robot ref, rows that apply)
        for entry, scenario, ds, ref in opened:
            log(f"[bench] scenario {scenario}: dataset")
            with clock.phase("generation"):
                t_data = time.perf_counter()
                if ds is None:
                    try:
                        ds = provider(entry, profile)
                    except RealLogMissingError as err:  # a real set whose log is not here: skipped, saying where
                        log(f"[bench] skipping scenario {scenario}: {err}")
                        skipped.append({"scenario": scenario, "task": "", "model": "", "reason": str(err)})
                        continue
                    ref = plan.robot_ref(ds)
            labels[scenario] = entry
            # Making (or finding) the dataset in this invocation: a generation that ran here is part of the wall time.
            dataset_seconds[scenario] = time.perf_counter() - t_data
            clock.record(out_dir, rows)  # a generation that took an hour is on record before any training
            for warning in import_warnings(ds):  # e.g. a time unit that does not fit: said here and in the README
                log(f"[bench] {scenario}: import warning: {warning}")
            # The analytic model: the profile's robot (or the dataset's), with its tool and nominal parameters.
            # An arm known for data only has none (its URDF rows are skipped, saying so).
            ds.meta["robot"] = ref.name
            robot = load_robot(ref.name, params=profile.params) if ref.described else None
            datasets[scenario] = ds
            ctx = BenchContext(profile, scenario, ds, robot, work_dir(plan, scenario, ds, work_root),
                               data_root, log=log, source=entry)
            scenarios.append((ctx, ref, _applicable_rows(plan, scenario, ds, skipped, log)))
        tcfg = _train_config(plan, executor, device)

        def score_untrained():  # while the queue trains: the rows that train nothing, scenario by scenario
            for ctx, ref, specs in scenarios:
                _bench_scenario(out_dir, ctx, [s for s in specs if not s.trains], predictions, rows, log, clock,
                                test_data=True)

        with clock.phase("training, and scoring the rows that train nothing"):
            _train_learned_rows(plan, scenarios, tcfg, log, executor, meanwhile=score_untrained)
        clock.record(out_dir, rows)
        with clock.phase("scoring the trained rows"):
            for ctx, ref, specs in scenarios:
                _bench_scenario(out_dir, ctx, [s for s in specs if s.trains], predictions, rows, log, clock,
                                test_data=False)
    meta = run_meta(profile, clock, rows, labels, skipped, datasets, dataset_seconds, machine_info())
    finish_record(out_dir, rows, meta)
    # The report is drawn from the files just written, exactly as ``hybrid-dyn report`` redraws it.
    write_report(out_dir, read_results(out_dir / "results.csv"), meta, log=log)
    return rows


def _train_config(plan: BenchPlan, executor=None, device=None):
    """The profile's training config as this run's workers use it: parallel workers train quietly (one
    progress bar over the models, not one per process), on ``device`` if given."""
    tcfg = plan.train_config()
    if plan.profile.workers > 1 or executor is not None:
        tcfg = dataclasses.replace(tcfg, progress=False)
    if device is not None:
        tcfg = dataclasses.replace(tcfg, device=device)
    return tcfg


def _train_learned_rows(plan: BenchPlan, scenarios: list, tcfg, log, executor=None, meanwhile=None) -> None:
    """Every scenario's learned rows trained in one queue on the profile's workers, dearest first
    (``training_queue.pretrain``). On local workers this process meanwhile fits what it fits itself (each
    scenario's identified model, whose residual nets then join the queue, and ``FIT_WHILE_WAITING``, the
    residual GP), then runs ``meanwhile()`` (the bench scores the rows that train nothing): both cores stay
    busy to the queue's end. A fit that fails here is fitted again, and its error raised with its row, when
    the row is scored."""
    import queue as queues

    from .identified_rows import FIT_WHILE_WAITING, RESIDUAL_ROWS, residual_training

    profile = plan.profile
    jobs = [(str(ctx.dataset.path), ref.name, plan.preset(s.name), str(ctx.work_dir / "models" / s.name), tcfg,
             profile.torch_threads) for ctx, ref, specs in scenarios for s in specs if s.name in PRESETS]
    log(f"[bench] training {len(jobs)} learned models of {len(scenarios)} scenarios on {profile.workers} workers")
    if profile.workers < 2 or executor is not None:  # serial, or a cluster's queue: the rows then score in turn
        pretrain(jobs, profile.workers, log=log, executor=executor)
        if meanwhile is not None:
            meanwhile()
        return
    later, failed = queues.Queue(), []

    def queued_later():  # the residual nets on the identified model, as their identification is fitted
        while (job := later.get()) is not None:
            yield job

    def train():  # the pool lives and dies in this thread (sim/executors.process_pool)
        try:
            pretrain(jobs, profile.workers, log=log, more=queued_later())
        except BaseException as err:  # noqa: BLE001  (raised again below, in the bench's thread)
            failed.append(err)

    # A daemon: an interrupt of this thread ends the process, and the workers die with it.
    worker_queue = threading.Thread(target=train, name="training-queue", daemon=True)
    worker_queue.start()
    try:
        for ctx, ref, specs in scenarios:
            for spec in specs:
                try:
                    if spec.name in RESIDUAL_ROWS:
                        config, out = residual_training(ctx, spec.name, tcfg)  # fits the identified model
                        later.put((str(ctx.dataset.path), ref.name, plan.preset(RESIDUAL_ROWS[spec.name]), str(out),
                                   config, profile.torch_threads))
                        log(f"[bench] {ctx.scenario}: {spec.name} queued to train in a worker (its identification "
                            "is fitted)")
                    elif spec.name in FIT_WHILE_WAITING:
                        spec.build(ctx.dataset, ctx)
                except Exception:  # noqa: BLE001  (raised again, with its row, when it is scored)
                    pass
    finally:
        later.put(None)  # the queue ends with the jobs it has
    if meanwhile is not None:
        meanwhile()
    while worker_queue.is_alive():
        worker_queue.join(timeout=1.0)  # a timed join: Ctrl-C reaches this thread
    if failed:
        raise failed[0]


def _bench_scenario(out_dir, ctx: BenchContext, specs: list, predictions, rows, log, clock: InvocationClock,
                    test_data: bool = True) -> None:
    """Rows ``specs`` of one scenario scored, each written to results.csv, predictions.h5 and curves.json as it
    finishes; ``rows`` grows. ``test_data``: write the scenario's test data to predictions.h5 first (once per
    scenario, before its first row)."""
    ds = ctx.dataset
    test = ds.split("test")
    if test_data:
        predictions.test_data(ctx.scenario, test, [t for t in dict.fromkeys(TASK_TARGET.values()) if t in ds.fields])
    if not specs:
        return
    norm = train_split_stats(ds)
    _score_rows(out_dir, ctx, specs, norm, test, predictions, rows, log, clock)


def _score_rows(out_dir, ctx, specs, norm, test, predictions, rows, log, clock) -> None:
    """Score ``specs`` in order, each written to results.csv, predictions.h5 and curves.json as it finishes (a
    learned row whose model the queue did not leave trained trains in its build)."""
    scenario = ctx.scenario
    for spec in tqdm(specs, desc=f"bench {scenario}", unit="model"):
        t0 = time.perf_counter()
        try:
            row = score_row(spec, ctx, norm)
        except Exception as err:  # a failed model is a row, not a crash
            row = {"task": spec.task, "scenario": scenario, "model": spec.name, "family": spec.family,
                   "status": "failed", "error": f"{type(err).__name__}: {err}"}
            log(f"[bench] {spec.name} FAILED: {err}\n{traceback.format_exc(limit=3)}")
        rows.append(row)
        # First: a row in results.csv always has its predictions (report checks them), implausible ones too.
        if row["status"] in SCORED_STATUSES:
            predictions.row(scenario, spec.task, spec.name, [i.name for i in test],
                            ctx.cache.pop((spec.task, spec.name)))
        record_row(out_dir, rows, clock)
        log(f"[bench] {scenario} {spec.task:12s} {spec.name:22s} rmse={row.get('rmse', float('nan')):.4g} "
            f"({time.perf_counter() - t0:.1f} s){'' if row['status'] == 'ok' else ' ' + row['status']}"
            if row["status"] in SCORED_STATUSES else
            f"[bench] {scenario} {spec.name} failed")


def _applicable_rows(plan: BenchPlan, scenario: str, ds: Dataset, skipped: list, log) -> list:
    """The profile's rows that apply to ``ds``; each that does not is logged and added to ``skipped``."""
    specs = []
    for r in plan.selected_rows():
        reason = plan.skip_reason(r, ds)
        if reason is None:
            specs.append(r)
        else:
            log(f"[bench] {scenario}: skipping {r.name} ({r.task}): {reason}")
            skipped.append({"scenario": scenario, "task": r.task, "model": r.name, "reason": reason})
    return specs
