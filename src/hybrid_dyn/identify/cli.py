"""CLI: ``hybrid-dyn identify`` (fit a parameter file) and ``hybrid-dyn excitation`` (record data for it)."""
from __future__ import annotations

import numpy as np


def register(sub) -> None:
    from .identification_methods import IDENTIFICATION_METHODS

    p = sub.add_parser("identify")
    p.add_argument("--data", required=True, help="dataset directory (toolkit format)")
    p.add_argument("--fit", choices=list(IDENTIFICATION_METHODS), default="consistent",
                   help="the identification method (default consistent): "
                        + "; ".join(f"{m.name}: {m.summary}" for m in IDENTIFICATION_METHODS.values()))
    p.add_argument("--out", required=True, help="parameter JSON to write (load_robot(..., params=OUT) reads it)")
    p.add_argument("--robot", default=None, help="nominal robot (default: the dataset's), e.g. panda[tool=none]")
    p.add_argument("--tool", default=None, help="its tool: none (the bare flange), a tool .urdf, or the URDF's own")
    p.add_argument("--splits", default="train,val", help="splits to fit on, comma-separated (default train,val)")
    p.add_argument("--acceleration", choices=("measured", "zero-phase"), default="measured",
                   help="use the dataset's qdd or re-estimate it offline without delay")
    p.set_defaults(func=cmd_identify)

    p = sub.add_parser("excitation")
    p.add_argument("--out", required=True, help="dataset directory to write")
    p.add_argument("--scenario", default="mismatch-ext", help="plant of this scenario (its pulses are switched off)")
    p.add_argument("--runs", type=int, default=2, help="runs (instances) of the trajectory, independent noise")
    p.add_argument("--periods", type=float, default=2.0, help="trajectory periods per run")
    p.add_argument("--max-iter", type=int, default=150, help="IPOPT iterations of the design")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_excitation)


def cmd_identify(args) -> int:
    from ..analytic.robot import load_robot
    from ..data import load_dataset
    from .identified_model import identify

    ds = load_dataset(args.data)
    robot = load_robot(args.robot or ds.meta.get("robot", "panda"), tool=args.tool)
    splits = tuple(s for s in args.splits.split(",") if s)
    model = identify(ds, args.fit, robot, splits=splits, acceleration=args.acceleration)
    model.save(args.out)
    fit = model.fit
    rmse = np.asarray(fit["rmse_per_joint"])
    print(f"{args.fit}: {fit['n_samples']} samples, {fit['n_base']} base parameters, "
          f"condition number of the base regressor {fit['condition_number']:.1f}")
    print("fit RMSE per joint [Nm]: " + " ".join(f"{x:.4f}" for x in rmse) + f"  (all {np.sqrt(np.mean(rmse**2)):.4f})")
    print(f"physically consistent: {fit['physically_consistent']}" +
          (f"  (IPOPT: {fit['ipopt_status']}, {fit['iterations']} iterations)" if "ipopt_status" in fit else ""))
    for w in fit["warnings"]:
        print(f"warning: {w}")
    for b in fit["implausible"]:
        print(f"warning: implausible parameters: {b}")
    print(f"wrote {args.out}")
    return 0


def cmd_excitation(args) -> int:
    from ..sim.scenarios import scenario_config
    from .excitation import ExcitationConfig, design_excitation
    from .experiment import record_excitation_dataset

    config = scenario_config(args.scenario, seed=args.seed)
    robot = config.nominal_robot()
    traj, report = design_excitation(robot, ExcitationConfig(max_iter=args.max_iter, seed=args.seed))
    print(f"excitation: condition number {report['condition_start']:.1f} (random start) -> {report['condition']:.1f} "
          f"(IPOPT: {report['ipopt_status']}, {report['iterations']} iterations)")
    record_excitation_dataset(args.out, config, traj, n_instances=args.runs, periods=args.periods, seed=args.seed)
    print(f"wrote {args.out}")
    return 0
