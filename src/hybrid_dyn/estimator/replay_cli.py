"""CLI: ``hybrid-dyn estimate SPEC --method M [--model DIR] --out OUT.mcap|OUT.csv`` (``estimator/replay.py``) and
``hybrid-dyn calibrate DATASET --params FILE --out CAL.json`` (``estimator/calibrate.py``)."""
from __future__ import annotations


def resolution(text: str):
    """``--encoder-resolution``: "auto" (resolved with the robot's description, by the estimator) or a number [rad]."""
    return text if text == "auto" else float(text)


def register(sub) -> None:
    from ..analytic.methods import DEFAULT_METHOD, TIP_FORCE_METHODS

    p = sub.add_parser("estimate")
    p.add_argument("spec", help="the log's import spec (TOML; a ROS bag's names its topics in [ros]: "
                                "docs/from_a_ros_bag.md), or the name of a shipped real set (real-panda, ...)")
    p.add_argument("--method", default=DEFAULT_METHOD,
                   help=f"the analytic estimator ({', '.join(TIP_FORCE_METHODS)}); default {DEFAULT_METHOD} (joint "
                        "torques; a log with a base sensor only: base-momentum)")
    p.add_argument("--model", default=None, help="a trained tip-force model folder instead of --method")
    p.add_argument("--encoder-resolution", type=resolution, default=None,
                   help="the log's joint-encoder resolution [rad]; default: the spec's [encoders] (0 on the shipped "
                        "real logs: the arm's own qd), else auto: the robot description's (1e-5 on the Panda); 0 "
                        "for q and qd as given")
    p.add_argument("--params", default=None,
                   help="the torque model: a parameter set or an identified file (hybrid-dyn identify): its inertials, "
                        "friction and declared springs")
    p.add_argument("--residual", default=None,
                   help="a hybrid: a residual GP folder fitted on the --params file (the bench's gp-residual-identified)")
    p.add_argument("--calibration", default=None,
                   help="error bars, bandwidth and max_sigma calibrated on this arm for that model "
                        "(hybrid-dyn calibrate; docs/estimator.md)")
    p.add_argument("--out", required=True, help="OUT.mcap (a ROS 2 bag: /tip_force, /tip_force/status) or OUT.csv; "
                                                "never overwritten; OUT.png beside it where the log has a tip sensor")
    p.add_argument("--keep-partial", action="store_true",
                   help="a damaged ROS bag: estimate from the rows read before the damage (the report says where "
                        "it stopped) instead of refusing it")
    p.set_defaults(func=cmd_estimate)

    p = sub.add_parser("calibrate")
    p.add_argument("data", help="an imported free-motion log of your arm (hybrid-dyn import; nothing touches the tool)")
    p.add_argument("--params", default=None, help="the torque model to calibrate: an identified file (hybrid-dyn "
                                                  "identify, fitted on other splits) or a parameter set; default the "
                                                  "description's own")
    p.add_argument("--residual", default=None, help="a hybrid: a residual GP folder fitted on the --params file")
    p.add_argument("--methods", default="torques-pinv,momentum-observer,kalman-fusion",
                   help="the joint-torque methods to calibrate, comma-separated")
    p.add_argument("--split", default="val", help="the dataset's split to calibrate on (default val)")
    p.add_argument("--encoder-resolution", type=resolution, default=0.0,
                   help="the log's encoders, as the estimator will read them [rad]; default 0: q and qd as logged")
    p.add_argument("--out", required=True, help="the calibration file to write (JSON; never overwritten)")
    p.set_defaults(func=cmd_calibrate)


def cmd_estimate(args) -> int:
    from ..data.logs.importer import read_spec
    from .replay import check_outputs, estimate_to

    from pathlib import Path

    from ..data.logs.real_logs import REAL_SETS, real_spec_path

    check_outputs(args.out)  # before the log is read: a taken name costs nothing
    spec = real_spec_path(args.spec) if args.spec in REAL_SETS and not Path(args.spec).exists() else args.spec
    summary, report, written, info = estimate_to(read_spec(spec), args.out, method=args.method,
                                                 model=args.model, encoder_resolution=args.encoder_resolution,
                                                 keep_partial=args.keep_partial, params=args.params,
                                                 calibration=args.calibration, residual=args.residual)
    print(report.text(max_per_kind=5))
    print(f"{info['method']}: {summary.n} samples estimated at {info['call_hz']:.6g} Hz; status {summary.statuses}")
    rms = summary.rms()
    if rms is not None:
        print(f"against the tip sensor: {rms[0]:.4f} N RMS over the {rms[1]} samples with status ok")
    for path in written:
        print(f"written: {path}")
    return 0


def cmd_calibrate(args) -> int:
    from pathlib import Path

    import numpy as np

    from ..analytic.robot import load_robot
    from ..data import load_dataset
    from .calibrate import calibrate
    from .calibration import CalibrationError
    from .torque_model import JointTorqueModel

    if Path(args.out).exists():
        raise CalibrationError(f"{args.out} exists: calibrate to a new file")
    ds = load_dataset(args.data)
    parts = ds.split(args.split)
    if not parts:
        raise CalibrationError(f"{args.data} has no {args.split!r} split to calibrate on")
    robot = load_robot(ds.meta.get("robot", "panda"), params=args.params, num_threads=1)
    model = None if args.params is None else JointTorqueModel.from_params(args.params, robot)
    if args.residual is not None:
        if model is None:
            raise CalibrationError("--residual corrects an identified model: give its file as --params")
        model = model.with_residual_gp(args.residual, robot)
    rate = 1.0 / float(np.median(np.concatenate([np.diff(np.asarray(i["t"], float)) for i in parts])))
    methods = [m for m in args.methods.split(",") if m]
    before = [i for s in ("train", "val", "test") if s != args.split for i in ds.split(s)]
    cal = calibrate(robot, methods, parts, rate, torque_model=model, progress=print, before=before,
                    source={"data": str(args.data), "split": args.split, "params": args.params},
                    encoder_resolution=args.encoder_resolution)
    if not cal.methods:
        raise CalibrationError(f"nothing was calibrated ({cal.source.get('not_calibrated') or 'no methods given'}); "
                               f"{args.out} not written")
    cal.save(args.out)
    print(f"wrote {args.out}")
    return 0
