"""The training queue: the learned rows trained in parallel before they are scored, one single-threaded model per
job (``pretrain``, dearest first, then the jobs queued after them: the bench's residual nets on the identified
model, as their identification is fitted)."""
from __future__ import annotations

from tqdm.auto import tqdm

from ..data import load_dataset


def _train_job(args) -> tuple[str, str | None]:
    """Train one learned row in a worker process (single-threaded torch)."""
    dataset_path, robot, preset, out_dir, train_config, threads = args
    set_torch_threads(threads)
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


def pretrain(jobs: list, workers: int, log=print, executor=None, more=None) -> None:
    """Train the learned rows in parallel, one single-threaded model per job.

    ``executor``: where the jobs run (``sim/executors.py``, as for generation): local
    processes by default (serial for one worker), or a Ray cluster. Each model's training
    is seeded on its own and reads and writes only paths in its job, so the model files do
    not depend on the executor, the worker count or the order; finished models are reused
    on a rerun (on a cluster, the data and model folders must be on a file system every
    node sees: docs/cluster.md). The dearest models are queued first
    (:func:`epoch_cost_rank`): queued in declaration order, the DeLaN rows came last and
    one core idled while the other finished them. Local workers die with this process, and
    an interrupt stops them instead of waiting for every queued model. ``more``: an iterator of
    further jobs queued after these, as it yields them (it may block until a job is ready).
    """
    if not jobs and more is None:
        return
    import itertools

    from ..sim.executors import make_executor

    jobs = sorted(jobs, key=lambda job: epoch_cost_rank(job[2]))  # stable: declaration order within a rank
    executor = executor or make_executor(workers)
    queued = ((job,) for job in itertools.chain(jobs, more or ()))
    results = executor.map_unordered(_train_job, queued)
    for preset, err in tqdm(results, total=None if more is not None else len(jobs), desc="training", unit="model"):
        if err:
            log(f"[bench] training {preset} failed: {err}")


def set_torch_threads(n: int) -> None:
    try:
        import torch
    except ImportError:  # pragma: no cover
        return
    torch.set_num_threads(n)
