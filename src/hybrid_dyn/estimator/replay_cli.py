"""CLI: ``hybrid-dyn estimate SPEC --method M [--model DIR] --out OUT.mcap|OUT.csv`` (``estimator/replay.py``)."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("estimate", help="replay a recorded log (a ROS bag, CSV, ...) through the streaming tip-force "
                                        "estimator; write /tip_force to an MCAP bag or a CSV")
    p.add_argument("spec", help="the log's import spec (TOML; a ROS bag's names its topics in [ros]: "
                                "docs/from_a_ros_bag.md)")
    p.add_argument("--method", default="base-momentum",
                   help="the analytic estimator (base-momentum, kalman-fusion, momentum-observer, base-wrench, "
                        "torques-pinv); default base-momentum")
    p.add_argument("--model", default=None, help="a trained tip-force model folder instead of --method")
    p.add_argument("--encoder-resolution", type=float, default=None,
                   help="the log's joint-encoder resolution [rad]; default the robot description's (1e-5 on the "
                        "Panda); 0 for exact q and qd (a simulation's)")
    p.add_argument("--out", required=True, help="OUT.mcap (a ROS 2 bag: /tip_force, /tip_force/status) or OUT.csv; "
                                                "never overwritten; OUT.png beside it where the log has a tip sensor")
    p.set_defaults(func=cmd_estimate)


def cmd_estimate(args) -> int:
    from ..data.logs.importer import read_spec
    from .replay import check_outputs, replay_log, write_estimate

    check_outputs(args.out)  # before the log is read: a taken name costs nothing
    resolution = "auto" if args.encoder_resolution is None else args.encoder_resolution
    replay, report = replay_log(read_spec(args.spec), method=args.method, model=args.model,
                                encoder_resolution=resolution)
    print(report.text(max_per_kind=5))
    statuses = {}
    for s in replay.status:
        key = s.split(":")[0]
        statuses[key] = statuses.get(key, 0) + 1
    print(f"{replay.method}: {len(replay.t)} samples estimated at {replay.call_hz:.6g} Hz"
          f"; status {statuses}")
    rms = replay.rms_against_truth()
    if rms is not None:
        print(f"against the tip sensor: {rms[0]:.4f} N RMS over the {rms[1]} samples with status ok")
    for path in write_estimate(replay, args.out):
        print(f"written: {path}")
    return 0
