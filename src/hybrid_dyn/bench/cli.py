"""CLI: hybrid-dyn bench."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("bench", help="every model family on the same data; writes results.csv, tables, figures")
    p.add_argument("--profile", default="quick", help="quick | default | seed-sim | paper (| real)")
    p.add_argument("--recipe", default=None, help="training recipe of the learned rows: default or seed "
                   "(default: the profile's)")
    p.add_argument("--out", default=None, help="report folder (default: reports/<profile>)")
    p.add_argument("--data-root", default=None, help="dataset cache (default: ./data or $HYBRID_DYN_DATA)")
    p.add_argument("--work-root", default=None, help="trained-model cache (default: ./runs or $HYBRID_DYN_RUNS)")
    p.add_argument("--workers", type=int, default=None, help="generator processes")
    p.set_defaults(func=cmd_bench)


def cmd_bench(args) -> int:
    import dataclasses

    from .profiles import get_profile
    from .runner import run_bench

    profile = get_profile(args.profile)
    if args.workers:
        profile = dataclasses.replace(profile, workers=args.workers)
    if args.recipe:
        from ..learn.train import RECIPES
        from ..errors import UsageError

        if args.recipe not in RECIPES:
            raise UsageError(f"unknown training recipe {args.recipe!r}; known: {', '.join(RECIPES)}")
        profile = dataclasses.replace(profile, recipe=args.recipe)
    out = args.out or f"reports/{profile.name}"
    rows = run_bench(profile, out, data_root=args.data_root, work_root=args.work_root)
    n_ok = sum(r.get("status") == "ok" for r in rows)
    print(f"[bench] {n_ok}/{len(rows)} rows ok; report in {out}/README.md")
    return 0 if n_ok == len(rows) else 1
