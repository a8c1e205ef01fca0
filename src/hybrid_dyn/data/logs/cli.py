"""CLI: ``hybrid-dyn import --spec spec.toml --out DIR`` (real robot logs)."""
from __future__ import annotations

import json
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("import")
    p.add_argument("--spec", required=True, help="the import spec (TOML; see docs/bring_your_own_log.md), or the name "
                   "of a real set whose spec ships with the package (real-kuka, real-baxter, real-sarcos, real-panda)")
    p.add_argument("--out", required=True, help="the dataset directory to write")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing dataset at --out (only a hybrid-dyn dataset holding nothing but its own "
                        "files; anything else is refused)")
    p.add_argument("--strict", action="store_true", help="fail on any row problem instead of dropping the row")
    p.add_argument("--robot", default=None,
                   help="the logged robot, instead of the spec's: a robots/ name, an example-robot-data arm (ur10), "
                        "a .urdf path, a data-only name; see docs/bring_your_own_log.md")
    p.add_argument("--tool", default=None,
                   help="what the arm carried, instead of the spec's: none (the bare flange), a tool .urdf, or the "
                        "URDF's own (hand for the Panda)")
    p.add_argument("--keep-partial", action="store_true",
                   help="a damaged ROS bag: keep the rows read before the damage (the report says where it stopped) "
                        "instead of refusing it")
    p.add_argument("--report", action="store_true", help="print every row problem, not the first few per kind")
    p.add_argument("--json", action="store_true", help="print the report summary as JSON")
    p.set_defaults(func=cmd_import)


def cmd_import(args) -> int:
    from ...description import parse_robot_name, resolve_robot
    from .importer import import_log, read_spec
    from .real_logs import REAL_SETS, real_spec_path

    # A shipped set by name: its spec lives inside the installed package, whose path a user need not know.
    path = real_spec_path(args.spec) if args.spec in REAL_SETS and not Path(args.spec).exists() else args.spec
    spec = read_spec(path)
    if args.robot is not None or args.tool is not None:  # the options replace the spec's robot or tool
        base, tool, payload = parse_robot_name(args.robot or spec.robot)
        spec.robot = resolve_robot(base, tool=args.tool if args.tool is not None else tool, payload=payload).name
    report = import_log(spec, args.out, overwrite=args.overwrite, strict=args.strict,
                        keep_partial=args.keep_partial)
    if args.json:
        print(json.dumps({"path": str(report.path), **report.summary()}, indent=1))
    else:
        print(report.text(max_per_kind=10**9 if args.report else 5))
        print(f"dataset written to {report.path} (full report: {report.path}/import_report.txt)")
    return 0
