"""CLI: hybrid-dyn bench (a built-in profile, or any datasets: --data DIR ...), study NAME, compare A B and report DIR."""
from __future__ import annotations

from ..registry import help_listing


def _profiles():
    from .profiles import PROFILES

    return PROFILES


def _families():
    from .families import FAMILIES

    return FAMILIES


def _rows():  # the rows' modules import torch: only when the help is printed
    from .catalog import ROWS

    return ROWS


def _studies():
    from .studies import STUDIES

    return STUDIES


def _recipes():
    from ..learn.recipes import RECIPES

    return RECIPES


# Help texts name {profiles}, {families}, {rows}, {studies}, {recipes}: read from the registries when printed.
_HELP = help_listing(profiles=_profiles, families=_families, rows=_rows, studies=_studies, recipes=_recipes)


# The bench's text options that change or narrow its profile (each None when not given), in --help's order.
_PROFILE_CHANGES = (
    ("--robot", "the analytic model's robot for every dataset, instead of each dataset's own "
                "(e.g. panda[tool=none]; see hybrid_dyn.description.ROBOT_NAME_HELP)"),
    ("--params", "nominal parameter set of the analytic rows and residual priors (a name such as franka_official, "
                 "or a parameter JSON path)"),
    ("--tool", "the robot's tool: none (the bare flange) or a tool .urdf path"),
    ("--recipe", "training recipe of the learned rows: {recipes} (default: the profile's)"),
    ("--families", "comma-separated row families to run instead of the profile's: {families}"),
    ("--rows", "comma-separated row names to run instead of the profile's (with --families: both): {rows}"),
    ("--scenarios", "comma-separated scenarios of the profile to run, instead of all of them "
                    "(e.g. --profile real --scenarios real-panda)"),
    ("--out", "report folder (default: reports/<profile>)"),
)


def register(sub) -> None:
    p = sub.add_parser("bench", formatter_class=_HELP)
    p.add_argument("--profile", default=None, help="a declared profile: {profiles} (default: quick, "
                   "or the datasets of --data)")
    p.add_argument("--data", action="append", default=None, metavar="DIR",
                   help="a dataset in the toolkit's format, simulated or imported (repeat for more): every row that "
                   "applies runs on it, the rest are skipped with their reason")
    for flag, text in _PROFILE_CHANGES:
        p.add_argument(flag, default=None, help=text)
    _where_options(p)
    p.add_argument("--device", default=None, help="training device: cpu, cuda or cuda:N (default: the profile's, "
                   "auto: CUDA where present)")
    p.add_argument("--gpus-per-job", type=float, default=0.0,
                   help="with --executor ray: GPUs each training job reserves (fractions share one GPU)")
    p.set_defaults(func=cmd_bench)

    st = sub.add_parser("study", formatter_class=_HELP)
    st.add_argument("name", help="a declared study: {studies}")
    st.add_argument("--report", default=None, help="the profile's own report, the study's reference point "
                    "(default: reports/<profile>)")
    st.add_argument("--out", default=None, help="summary folder (default: the study's, reports/studies/<study>; data-scaling: "
                    "reports/seed-sim/data-scaling)")
    _where_options(st)
    st.set_defaults(func=cmd_study)

    cmp = sub.add_parser("compare")
    cmp.add_argument("a", help="a report folder (e.g. on less data)")
    cmp.add_argument("b", help="another report folder (e.g. on more data)")
    cmp.add_argument("--out", default=None, help="also write the comparison to this markdown file (a new file, "
                     "or one an earlier compare wrote and nobody edited since: anything else is refused)")
    cmp.set_defaults(func=cmd_compare)

    r = sub.add_parser("report")
    r.add_argument("dir", help="a report folder written by hybrid-dyn bench (run.json, results.csv, ...)")
    r.set_defaults(func=cmd_report)


def _where_options(p) -> None:
    """Where a bench's data, models and jobs go: shared by ``bench`` and ``study`` (a study runs benches)."""
    p.add_argument("--data-root", default=None, help="dataset cache (default: ./data or $HYBRID_DYN_DATA)")
    p.add_argument("--work-root", default=None, help="trained-model cache (default: ./runs or $HYBRID_DYN_RUNS)")
    p.add_argument("--workers", type=int, default=None, help="local processes generating and training")
    p.add_argument("--executor", choices=("local", "ray"), default="local",
                   help="where generation and training jobs run: local processes, or a Ray cluster (docs/cluster.md)")
    p.add_argument("--ray-address", default=None, help="a running Ray cluster (e.g. auto, ray://head:10001); "
                   "default with --executor ray: a local Ray instance of --workers CPUs")


def _executor(args, workers: int, local_pool: bool = False):
    """The executor ``--executor``/``--ray-address`` name, of ``workers`` local processes or Ray CPUs. For
    plain local jobs: None (the bench's own pool, of the profile's workers) unless ``local_pool``."""
    if args.executor == "local" and not args.ray_address and not local_pool:
        return None
    from ..sim.executors import make_executor

    return make_executor(workers, args.executor, args.ray_address)


def cmd_bench(args) -> int:
    import dataclasses

    from ..errors import UsageError
    from .profiles import PROFILES, profile_for_data
    from .runner import run_bench

    if args.data and args.profile:
        raise UsageError("give --profile or --data, not both (a profile names its own datasets)")
    if args.data:
        profile = profile_for_data(args.data, robot=args.robot, params=args.params, tool=args.tool)
    else:
        profile = PROFILES.lookup(args.profile or "quick")
        if args.robot or args.params or args.tool:
            profile = dataclasses.replace(profile, robot=args.robot, params=args.params, tool=args.tool)
    if args.workers:
        profile = dataclasses.replace(profile, workers=args.workers)
    if args.scenarios is not None:
        if args.data:
            raise UsageError("--scenarios narrows a profile's scenarios; with --data, name the datasets instead")
        wanted = _names(args.scenarios)
        unknown = [s for s in wanted if s not in profile.scenarios]
        if unknown or not wanted:
            raise UsageError(f"--scenarios {args.scenarios!r}: {unknown or 'none named'} not among profile "
                             f"{profile.name!r}'s scenarios ({', '.join(profile.scenarios)})")
        profile = dataclasses.replace(profile, scenarios=wanted)
    if args.families is not None or args.rows is not None:  # an unknown name is refused by the profile itself
        families, names = _names(args.families), _names(args.rows)
        if not families and not names:
            raise UsageError("--families and --rows name no row to run")
        profile = dataclasses.replace(profile, families=families, rows=names)
    if args.recipe:  # an unknown recipe is refused by the profile itself
        from ..learn.recipes import RECIPE_ALIASES

        if args.recipe in RECIPE_ALIASES:  # an old name: warned once, and recorded (run.json) by its new name
            from ..deprecation import warn_renamed

            warn_renamed("training recipe", args.recipe, RECIPE_ALIASES[args.recipe])
            args.recipe = RECIPE_ALIASES[args.recipe]
        profile = dataclasses.replace(profile, recipe=args.recipe)
    if args.data and not args.out:
        raise UsageError("--data needs --out REPORT (the report folder)")
    out = args.out or f"reports/{profile.name}"
    rows = run_bench(profile, out, data_root=args.data_root, work_root=args.work_root,
                     executor=_executor(args, profile.workers),
                     device=args.device, gpus_per_job=args.gpus_per_job)
    n_ok = sum(r.get("status") == "ok" for r in rows)
    # An implausible row is a result (scored, its bodies named in the report), not a failure: said, exit 0.
    n_implausible = sum(r.get("status") == "implausible" for r in rows)
    implausible = f", {n_implausible} implausible (identified parameters outside the robot's bounds)" \
        if n_implausible else ""
    print(f"[bench] {n_ok}/{len(rows)} rows ok{implausible}; report in {out}/README.md")
    # No row run is no result (a named scenario whose log is missing: each skip and its reason is in the report).
    return 0 if rows and n_ok + n_implausible == len(rows) else 1


def _names(text: str | None) -> tuple:
    return tuple(n.strip() for n in (text or "").split(",") if n.strip())


def cmd_study(args) -> int:
    from pathlib import Path

    from .profiles import PROFILES
    from .runner import default_work_root
    from .studies import STUDIES, run_study

    study = STUDIES.lookup(args.name)
    workers = args.workers or PROFILES.lookup(study.profile).workers
    report = Path(args.report or f"reports/{study.profile}")
    out = Path(args.out) if args.out else study.default_out()
    run_study(study, report, out, work_root=default_work_root(args.work_root), data_root=args.data_root,
              executor=_executor(args, workers, local_pool=True))  # --workers is the study's, not its profile's
    print(f"[study] {study.name}: summary in {out}/README.md")
    return 0


def cmd_compare(args) -> int:
    from pathlib import Path

    from ..errors import UsageError
    from ..outputs import check_own_text, write_own_text
    from .compare import compare_reports

    for d in (args.a, args.b):
        if not (Path(d) / "results.csv").is_file() or not (Path(d) / "run.json").is_file():
            raise UsageError(f"{d} holds no bench report (results.csv and run.json)")
    if args.out:  # refused before any work: the user's own file there
        check_own_text(args.out, "compare")
    text = compare_reports(Path(args.a), Path(args.b), command=f"hybrid-dyn compare {args.a} {args.b}")
    print(text)
    if args.out:  # a file of its own is replaced; a user's is refused (outputs.py)
        write_own_text(args.out, text + "\n", "compare")
    return 0


def cmd_report(args) -> int:
    from .report import rebuild_report

    notes = rebuild_report(args.dir)
    print(f"[report] redrawn from files in {args.dir}" + (f" ({len(notes)} note(s) above)" if notes else ""))
    return 0
