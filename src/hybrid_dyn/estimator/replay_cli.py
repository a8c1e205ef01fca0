"""CLI: ``hybrid-dyn estimate SPEC --method M [--model DIR] --out OUT.mcap|OUT.csv`` (``estimator/replay.py``)."""
from __future__ import annotations


def resolution(text: str):
    """``--encoder-resolution``: "auto" (resolved with the robot's description, by the estimator) or a number [rad]."""
    return text if text == "auto" else float(text)


def register(sub) -> None:
    from ..analytic.methods import DEFAULT_METHOD, TIP_FORCE_METHODS

    p = sub.add_parser("estimate")
    p.add_argument("spec", help="the log's import spec (TOML; a ROS bag's names its topics in [ros]: "
                                "docs/from_a_ros_bag.md)")
    p.add_argument("--method", default=DEFAULT_METHOD,
                   help=f"the analytic estimator ({', '.join(TIP_FORCE_METHODS)}); default {DEFAULT_METHOD} (joint "
                        "torques; a log with a base sensor only: base-momentum)")
    p.add_argument("--model", default=None, help="a trained tip-force model folder instead of --method")
    p.add_argument("--encoder-resolution", type=resolution, default="auto",
                   help="the log's joint-encoder resolution [rad]; default auto: the robot description's (1e-5 on "
                        "the Panda); 0 for exact q and qd (a simulation's)")
    p.add_argument("--out", required=True, help="OUT.mcap (a ROS 2 bag: /tip_force, /tip_force/status) or OUT.csv; "
                                                "never overwritten; OUT.png beside it where the log has a tip sensor")
    p.add_argument("--keep-partial", action="store_true",
                   help="a damaged ROS bag: estimate from the rows read before the damage (the report says where "
                        "it stopped) instead of refusing it")
    p.set_defaults(func=cmd_estimate)


def cmd_estimate(args) -> int:
    from ..data.logs.importer import read_spec
    from .replay import check_outputs, estimate_to

    check_outputs(args.out)  # before the log is read: a taken name costs nothing
    summary, report, written, info = estimate_to(read_spec(args.spec), args.out, method=args.method,
                                                 model=args.model, encoder_resolution=args.encoder_resolution,
                                                 keep_partial=args.keep_partial)
    print(report.text(max_per_kind=5))
    print(f"{info['method']}: {summary.n} samples estimated at {info['call_hz']:.6g} Hz; status {summary.statuses}")
    rms = summary.rms()
    if rms is not None:
        print(f"against the tip sensor: {rms[0]:.4f} N RMS over the {rms[1]} samples with status ok")
    for path in written:
        print(f"written: {path}")
    return 0
