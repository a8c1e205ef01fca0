"""The benchmark harness: every model family on the same data, one results table.

For each scenario of a profile: make (or reuse) the dataset, then for each
model row build a predictor (analytic rows: nothing to train; learned rows:
train or reuse), predict every sample of the validation and test splits, and
score all rows with the same metrics (``metrics.py``) against the same logged
targets. A row that fails is written with its error, not dropped.

Targets: tip force -> the logged ``tip_force``; joint torque -> the logged
commanded motor torque ``tau_m`` (friction included), as PROTOCOL 4 says.
Losses are MSE on targets standardised with the train split's statistics, for
analytic and learned rows alike. Sequence models are scored on every sample:
their first L-1 windows of each instance are edge-padded (``data/windows.py``),
exactly as a streaming estimator starts up.

The rows are those of the registry (``rows.py``; declared in ``analytic_rows.py``,
``learned_rows.py``, ``identified_rows.py``) that the profile names and that
apply to the dataset (``BenchPlan.skip_reason``); each row that does not is
logged and listed in run.json and the README with its reason. A scenario is a
simulated or real set's name, or any dataset's path (``hybrid-dyn bench --data``).

Files, each written atomically as rows finish (an interrupted bench keeps them):
results.csv and curves.json (``results.py``), predictions.h5 (``predictions.py``:
every row's test predictions and their targets), run.json. The report is then
drawn from those files alone (``report.write_report``), as ``hybrid-dyn report``
redraws it.
"""
from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import time
import traceback
from pathlib import Path
from typing import Callable

import numpy as np
from tqdm.auto import tqdm

from ..analytic.robot import load_robot
from ..data import Dataset, load_dataset
from ..data.logs.real_logs import RealLogMissingError
from ..data.splits import dataset_split_text
from ..errors import UsageError
from ..outputs import output_lock
from ..timing import time_calls
from .catalog import ROWS  # noqa: F401  (ROWS: every declared row)
from .integrity import DIGEST_KEY, REPORT_FILES, read_run_json, results_digest, row_key
from .invocations import InvocationClock, caches_empty, claim_report_dir
from .learned_rows import PRESET_ROWS
from .metrics import ErrorReport, answered, base_force_noise_rms, standardized_mse
from .predictions import PREDICTIONS_FILE, PredictionWriter
from .plan import BenchContext, BenchPlan, is_dataset_path, scenario_label
from .profiles import BenchProfile
from .report import machine_info, write_report
from .results import (COLUMNS, CURVES_FILE, SCORED_STATUSES, read_curves, write_json,  # noqa: F401  (re-exported)
                      read_results, write_curves, write_results)
from .row_checks import NOTE_SEPARATOR, review_row
from .rows import TASK_TARGET, Predictor, Row  # noqa: F401  (re-exported for callers)

# ---------------------------------------------------------------------- scoring
def _median_call_us(fn, inst, warmup_calls: int = 1, n_calls: int = 200) -> float:
    """The median time [us] of a row's single call on one run, fed its samples in order from the start
    (as a control loop feeds a stream); the first ``warmup_calls`` (at least one, at most all but the
    last sample) are not timed, then up to ``n_calls`` are (``timing.time_calls``)."""
    n = len(inst)
    warm = min(max(1, int(warmup_calls)), n - 1)
    for k in range(warm):
        fn(inst, k)
    wall, _ = time_calls(lambda k: fn(inst, k), range(warm, min(n, warm + n_calls)))
    return float(np.median(wall) * 1e6)


def score_row(spec: Row, ctx: BenchContext, norm: dict) -> dict:
    ds = ctx.dataset
    target = TASK_TARGET[spec.task]
    row = {"task": spec.task, "scenario": ctx.scenario, "model": spec.name, "family": spec.family}
    if target not in ds.fields:
        raise ValueError(f"the dataset has no {target!r} field")
    cpu0 = time.process_time()  # this process's CPU, every thread (BLAS, torch) included
    pred_obj = spec.build(ds, ctx)
    cpu1 = time.process_time()
    # A model trained elsewhere (a worker, an earlier invocation) brings its recorded CPU; else the build was the fit.
    train_cpu = cpu1 - cpu0 if pred_obj.train_cpu_seconds is None else pred_obj.train_cpu_seconds
    row.update(inputs=pred_obj.inputs, train_seconds=pred_obj.train_seconds, train_cpu_seconds=train_cpu,
               n_params=pred_obj.n_params)
    if pred_obj.prior_kept is not None:
        row["prior_kept"] = pred_obj.prior_kept
    if pred_obj.training is not None:
        t = pred_obj.training
        row.update(epochs=t["epochs"], stopped_by=t["stopped_by"], best_epoch=t["best_epoch"])
        row["curve"] = {"task": spec.task, **t}  # not a results.csv column: the runner keeps it in curves.json
    mean, std = norm[target]
    losses = {}
    for split in ("val", "test"):
        insts = ds.split(split)
        tgt = np.concatenate([i[target] for i in insts])  # also loads the files: I/O stays out of the timing
        t0 = time.perf_counter()
        preds = pred_obj.predict(insts)
        elapsed = time.perf_counter() - t0
        pred = np.concatenate(preds)
        ok = answered(pred)  # a refused sample (NaN) is no error: the answered share says how many there were
        losses[split] = standardized_mse(pred[ok], tgt[ok], mean, std)
        if split == "test":
            f_truth = (np.concatenate([i.truth.get("tip_force", i["tip_force"]) for i in insts])
                       if "tip_force" in ds.fields else None)
            report = ErrorReport.compute(pred, tgt, f_truth)
            if spec.task == "tip_force" and "base_wrench" in ds.fields:
                if "base-force-noise" not in ctx.cache:  # a property of the data: once per scenario
                    ctx.cache["base-force-noise"] = base_force_noise_rms(insts)
                row["noise_rms"] = ctx.cache["base-force-noise"]
            row["infer_us_per_sample"] = elapsed / len(pred) * 1e6
            ctx.cache[(spec.task, spec.name)] = preds
            test_target = tgt
    row.update(val_loss=losses["val"], test_loss=losses["test"], rmse=report.rmse, nmse=report.nmse,
               rmse_contact=report.rmse_contact, rmse_free=report.rmse_free, max_error=report.max_error,
               n_test_samples=report.n_samples, answered_share=report.answered_share,
               rmse_refused_as_zero=report.rmse_refused_as_zero)
    for j, v in enumerate(report.per_component):
        row[f"rmse_{j + 1}"] = float(v)
    if pred_obj.sigma_coverage is not None:
        row["sigma_coverage"] = pred_obj.sigma_coverage()
    if pred_obj.single_call is not None:
        row["infer_us_per_call"] = _median_call_us(pred_obj.single_call, ds.split("test")[0], pred_obj.warmup_calls)
    row["score_cpu_seconds"] = time.process_time() - cpu1  # val and test predictions, metrics, the timed calls
    # ok or implausible (identified parameters outside the robot's bounds), and what the numbers cannot show.
    row["status"], notes = review_row(spec, ctx, pred_obj, target, std, test_target)
    row["notes"] = NOTE_SEPARATOR.join(notes)
    return row


def train_split_stats(ds: Dataset) -> dict:
    """Per-component mean and std of each target over the train split (a std of 0, a constant training target,
    is kept: the losses standardised by it are undefined, ``metrics.standardized_mse``)."""
    out = {}
    for target in TASK_TARGET.values():
        if target in ds.fields:
            y = np.concatenate([i[target] for i in ds.split("train")])
            out[target] = (y.mean(0), y.std(0))
    return out


def _train_job(args) -> tuple[str, str | None]:
    """Train one learned row in a worker process (single-threaded torch)."""
    dataset_path, robot, preset, out_dir, train_config, threads = args
    _set_torch_threads(threads)
    from ..learn import train_model

    try:
        ds = load_dataset(dataset_path)
        ds.meta["robot"] = robot  # the bench's robot for this dataset (--robot / --tool), as score_row sees it
        train_model(ds, preset, out_dir, config=train_config, wait=True)  # another bench sharing runs/
        return _preset_name(preset), None
    except Exception as err:  # reported again, with its row, when the row is scored
        return _preset_name(preset), f"{type(err).__name__}: {err}"


def _preset_name(preset) -> str:
    """A job's preset by name (a job carries a name, or a Preset changed by the profile's preset_overrides)."""
    return preset if isinstance(preset, str) else preset.name


def epoch_cost_rank(preset) -> tuple:
    """A sort key that orders presets by their cost per epoch, dearest first.

    From the architecture alone: DeLaN (autograd through H(q) and V(q); with an LSTM
    residual the dearest), then LSTMs, conv nets, MLPs; within a kind, wider fronts and
    longer windows first. Measured on one thread on a default-profile scenario (144 k
    training windows): delan-residual 10.7 s per epoch, delan-friction 6.4, the 2 x 32
    LSTMs 5.0-5.9, the 32-unit residual LSTMs 2.7-4.0, the 16-unit LSTMs 1.4-2.5, conv
    1.1-1.6, MLPs 0.45-1.05.
    """
    from ..learn.kinds import cost_rank
    from ..learn.presets import PRESETS

    p = PRESETS.lookup(preset) if isinstance(preset, str) else preset
    kind = cost_rank(p)  # declared with the network kind (learn/kinds.py)
    return (-kind, -sum(p.front_units), -p.window, -p.fc_units)


def pretrain(jobs: list, workers: int, log=print, executor=None) -> None:
    """Train the learned rows in parallel, one single-threaded model per job.

    ``executor``: where the jobs run (``sim/executors.py``, as for generation): local
    processes by default (serial for one worker), or a Ray cluster. Each model's training
    is seeded on its own and reads and writes only paths in its job, so the model files do
    not depend on the executor, the worker count or the order; finished models are reused
    on a rerun (on a cluster, the data and model folders must be on a file system every
    node sees: docs/cluster.md). The dearest models are queued first
    (:func:`epoch_cost_rank`): queued in declaration order, the DeLaN rows came last and
    one core idled while the other finished them. Local workers die with this process, and
    an interrupt stops them instead of waiting for every queued model.
    """
    if not jobs:
        return
    from ..sim.executors import make_executor

    jobs = sorted(jobs, key=lambda job: epoch_cost_rank(job[2]))  # stable: declaration order within a rank
    executor = executor or make_executor(workers)
    results = executor.map_unordered(_train_job, [(job,) for job in jobs])
    for preset, err in tqdm(results, total=len(jobs), desc="training", unit="model"):
        if err:
            log(f"[bench] training {preset} failed: {err}")


def _set_torch_threads(n: int) -> None:
    try:
        import torch
    except ImportError:  # pragma: no cover
        return
    torch.set_num_threads(n)


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
    _set_torch_threads(profile.torch_threads)
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
        return _run_bench_locked(plan, out_dir, clock, data_root, work_root, provider, opened, log,
                                 train_executor, device)


def _import_warnings(ds) -> list[str]:
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
        for entry, scenario, ds, ref in opened:
            log(f"[bench] scenario {scenario}: dataset")
            t_data = time.perf_counter()
            if ds is None:
                try:
                    ds = provider(entry, profile)
                except RealLogMissingError as err:  # a real set whose log is not here: skipped, saying where to get it
                    log(f"[bench] skipping scenario {scenario}: {err}")
                    skipped.append({"scenario": scenario, "task": "", "model": "", "reason": str(err)})
                    continue
                ref = plan.robot_ref(ds)
            labels[scenario] = entry
            # Making (or finding) the dataset in this invocation: a generation that ran here is part of the wall time.
            dataset_seconds[scenario] = time.perf_counter() - t_data
            clock.record(out_dir, rows)  # a generation that took an hour is on record before any training
            for warning in _import_warnings(ds):  # e.g. a time unit that does not fit: said here and in the README
                log(f"[bench] {scenario}: import warning: {warning}")
            # The analytic model: the profile's robot (or the dataset's), with its tool and nominal parameters.
            # An arm known for data only has none (its URDF rows are skipped, saying so).
            ds.meta["robot"] = ref.name
            robot = load_robot(ref.name, params=profile.params) if ref.described else None
            datasets[scenario] = ds
            ctx = BenchContext(profile, scenario, ds, robot, work_dir(plan, scenario, ds, work_root),
                               data_root, log=log, source=entry)
            _bench_scenario(plan, out_dir, ctx, ref, predictions, rows, skipped, log, clock, executor, device)
    meta = _run_meta(profile, clock, rows, labels, skipped, datasets, dataset_seconds)
    # The files an earlier report drew here stay on record: this one removes those it no longer draws.
    meta[REPORT_FILES] = read_run_json(out_dir).get(REPORT_FILES) or []
    write_results(out_dir / "results.csv", rows)  # also when no row applied: the report reads it
    meta[DIGEST_KEY] = results_digest(out_dir / "results.csv", meta)  # what ``hybrid-dyn report`` checks against
    write_json(out_dir / "run.json", meta)
    # The report is drawn from the files just written, exactly as ``hybrid-dyn report`` redraws it.
    write_report(out_dir, read_results(out_dir / "results.csv"), meta, log=log)
    return rows


def _bench_scenario(plan: BenchPlan, out_dir, ctx: BenchContext, ref, predictions, rows, skipped, log,
                    clock: InvocationClock, executor=None, device=None) -> None:
    """One scenario's rows: those that apply are trained (the learned ones, in parallel) and scored, each
    written to results.csv, predictions.h5 and curves.json as it finishes; ``rows`` and ``skipped`` grow."""
    profile, scenario, ds = plan.profile, ctx.scenario, ctx.dataset
    norm = train_split_stats(ds)
    specs = _applicable_rows(plan, scenario, ds, skipped, log)
    test = ds.split("test")
    predictions.test_data(scenario, test, [t for t in dict.fromkeys(TASK_TARGET.values()) if t in ds.fields])
    # Parallel workers train quietly (one progress bar over the models, not one per process).
    tcfg = plan.train_config()
    if profile.workers > 1 or executor is not None:
        tcfg = dataclasses.replace(tcfg, progress=False)
    if device is not None:
        tcfg = dataclasses.replace(tcfg, device=device)
    # The presets' rows train in parallel first (the identified residuals need their fit first).
    jobs = [(str(ds.path), ref.name, plan.preset(s.name), str(ctx.work_dir / "models" / s.name), tcfg,
             profile.torch_threads) for s in specs if s.name in PRESET_ROWS]
    log(f"[bench] {scenario}: training {len(jobs)} learned models on {profile.workers} workers")
    pretrain(jobs, profile.workers, log=log, executor=executor)
    clock.record(out_dir, rows)
    with _background_training(ctx, specs, tcfg, ref.name, executor) as pending:
        _score_rows(out_dir, ctx, specs, norm, test, predictions, rows, log, clock, pending)


@contextlib.contextmanager
def _background_training(ctx: BenchContext, specs: list, tcfg, robot: str, executor):
    """The residual nets on the identified model (which ``pretrain`` cannot train: they need the identified
    fit first) trained in worker processes while this process fits and scores the other rows, on local
    workers beyond this process (``profile.workers - 1``); yields {row name: future}. Their row waits for its
    future before it is built, then finds the model trained (a worker's error is raised again by the build)."""
    from .identified_rows import RESIDUAL_ROWS, residual_training

    names = [s.name for s in specs if s.name in RESIDUAL_ROWS]
    if not names or ctx.profile.workers < 2 or executor is not None:
        yield {}
        return
    from ..sim.executors import process_pool

    jobs = {}
    try:
        for name in names:
            config, out = residual_training(ctx, name, tcfg)
            jobs[name] = (str(ctx.dataset.path), robot, ctx.plan.preset(RESIDUAL_ROWS[name]), str(out), config,
                          ctx.profile.torch_threads)
    except Exception as err:  # the identification failed: each row that needs it fails with it, named, when scored
        ctx.log(f"[bench] {ctx.scenario}: the residual nets on the identified model train when scored ({err})")
        yield {}
        return
    ctx.log(f"[bench] {ctx.scenario}: training {', '.join(jobs)} in a worker while this process fits and scores "
            "the other rows")
    with process_pool(min(len(jobs), ctx.profile.workers - 1)) as pool:
        yield {name: pool.submit(_train_job, job) for name, job in jobs.items()}


def _score_rows(out_dir, ctx, specs, norm, test, predictions, rows, log, clock, pending: dict) -> None:
    """Score ``specs`` in order, each written to results.csv, predictions.h5 and curves.json as it finishes;
    ``pending``: row name -> the future of its training in a worker (waited for before the row is built)."""
    from .identified_rows import FIT_WHILE_WAITING

    scenario = ctx.scenario
    for i, spec in enumerate(tqdm(specs, desc=f"bench {scenario}", unit="model")):
        if spec.name in pending:
            if not pending[spec.name].done():  # fit a later row's model meanwhile: its build then reads it
                for later in specs[i + 1:]:
                    if later.name in FIT_WHILE_WAITING:
                        try:
                            later.build(ctx.dataset, ctx)
                        except Exception:  # noqa: BLE001  (raised again, with its row, when it is scored)
                            pass
            pending[spec.name].result()
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
        write_results(out_dir / "results.csv", rows)
        clock.record(out_dir, rows)
        write_curves(out_dir / CURVES_FILE, rows)
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


def _run_meta(profile: BenchProfile, clock: InvocationClock, rows: list, labels: dict, skipped: list,
              datasets: dict, dataset_seconds: dict) -> dict:
    """run.json (before its digest): the profile, every invocation's wall time, the scenarios and rows not run,
    the machine and each dataset."""
    # Keep every invocation (``clock.previous``, read when the folder was claimed): a rerun
    # that reuses cached data and models is fast, and the first, full run's wall
    # time must not be overwritten by it.
    invocations = clock.invocations(rows, finished=True)
    wall = invocations[-1]["wall_seconds"]
    return {"bench_report": 1, "profile": profile.to_dict(), "wall_seconds": wall, "invocations": invocations,
            "scenarios": labels, "requested": clock.requested, "skipped": skipped, "machine": machine_info(),
            "datasets": {s: {"path": recorded_path(d.path), "checksum": d.checksum, "seed": d.meta.get("seed"),
                             "config_hash": d.meta.get("config_hash"), "robot": d.meta.get("robot"),
                             "split": dataset_split_text(d), "dataset_seconds": dataset_seconds.get(s),
                             **({"import_warnings": _import_warnings(d)} if _import_warnings(d) else {})}
                         for s, d in datasets.items()}}
