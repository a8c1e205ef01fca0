"""CLI: ``hybrid-dyn generate``, the DART dataset generator."""
from __future__ import annotations

import sys


def register(sub) -> None:
    from .generator_config import SIZES
    from .scenarios import SCENARIOS

    p = sub.add_parser("generate")
    p.add_argument("--scenario", choices=list(SCENARIOS), default="paper-ext",
                   help=". ".join(f"{s.name}: {s.description}" for s in SCENARIOS.values()))
    p.add_argument("--size", choices=SIZES, default="quick",
                   help="the dataset's size: quick: under a minute; default: ~0.4 M samples; paper: the seed's "
                        "1000 instances")
    p.add_argument("--out", required=True, help="dataset directory or fsspec URL (created in an existing folder; an "
                                                 "interrupted run there resumes; one run at a time)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=1,
                   help="local processes, or CPUs of a local Ray instance (the bytes do not depend on it)")
    p.add_argument("--executor", choices=("local", "ray"), default="local",
                   help="local processes (default) or Ray tasks (pip install 'hybrid-dyn[cluster]')")
    p.add_argument("--ray-address", default=None,
                   help="a running Ray cluster (e.g. auto, ray://head:10001); default: start Ray on this machine")
    p.add_argument("--no-noise", action="store_true", help="noise-free sensors (fields equal truth)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_generate)


def _check_args(args) -> None:
    """Refuse bad arguments before anything is written (generate_dataset checks the rest)."""
    from pathlib import Path

    from ..data.store import is_url
    from ..errors import OutputPathError, UsageError

    if not args.out.strip():
        raise UsageError("--out is empty: give the dataset directory (or an fsspec URL) to write")
    if args.seed < 0:
        raise UsageError(f"--seed must be >= 0, got {args.seed}")
    if args.workers < 1:
        raise UsageError(f"--workers must be >= 1, got {args.workers}")
    if not is_url(args.out):
        parent = Path(args.out).absolute().parent
        if not parent.is_dir():
            raise OutputPathError(f"--out {args.out}: its folder {parent} does not exist (create it first)")


def cmd_generate(args) -> int:
    import json

    from ..data import load_dataset
    from ..data.store import DatasetStore
    from .executors import make_executor
    from .generator import generate_dataset
    from .scenarios import noise_free, scenario_config

    _check_args(args)
    overrides = noise_free(args.scenario) if args.no_noise else {}
    cfg = scenario_config(args.scenario, args.size, seed=args.seed, **overrides)
    executor = make_executor(args.workers, args.executor, args.ray_address)
    out = generate_dataset(cfg, args.out, executor=executor, progress=not args.quiet)
    store = DatasetStore(out)
    if store.local is not None:
        ds = load_dataset(out)
        meta, checksum = ds.meta, ds.checksum
    else:  # a remote store: every file was checked on the way; summarise from the manifest
        meta = json.loads(store.read_text("manifest.json"))
        checksum = None
    rms = meta["tracking_error"]["rms_mean_per_joint"]
    print(f"{out}: {len(meta['instances'])} instances, {meta['n_samples']} samples at {meta['record_hz']:g} Hz, "
          f"config {meta['config_hash']}" + (f", checksum {checksum[:16]}" if checksum else ""))
    print("tracking RMS per joint [mrad]: " + " ".join(f"{1e3 * x:.2f}" for x in rms), file=sys.stdout)
    return 0
