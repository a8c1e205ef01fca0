"""Identified-model rows of the benchmark (issue 7): the strongest analytic baseline.

Per scenario, as on a real robot: an excitation trajectory (Fourier series
designed for the regressor's condition number, once per robot) is run on the
scenario's own plant with the external pulses off; the parameters are
identified from that run alone and then scored on the scenario's test split
like every other row. Design, identification run and fits are cached.

Rows:
  joint torque  identified-ols, identified-consistent, identified-sigmoid-friction,
                rnea+identified-friction (nominal RNEA + the Gaz law fitted jointly)
                identified-bw-tared (identified-sigmoid-friction minus J_v^T F, F from
                base-wrench-identified-tared: the contact torque removed with the base sensor)
  tip force     base-wrench-identified (the base-wrench method on the consistent set),
                base-wrench-identified-tared (the same on a base sensor tared per run)
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..analytic.tare import TARE_SECONDS, tare_samples, tared_base_wrench
from ..analytic.tip_force import contact_joint_torques, tip_force_from_base_wrench
from ..data import DatasetError, load_dataset

EXCITATION_ITERATIONS = {"quick": 30, "default": 150, "paper": 150}


def _identified(ctx) -> dict:
    """The fitted models of this scenario, computed once (cached in memory and on disk)."""
    if "identified" in ctx.cache:
        return ctx.cache["identified"]
    from ..identify.excitation import ExcitationConfig, FourierTrajectory, design_excitation
    from ..identify.experiment import record_excitation_dataset
    from ..identify.model import identify
    from ..sim.scenarios import scenario_config

    prof = ctx.profile
    root = Path(ctx.data_root)
    root.mkdir(parents=True, exist_ok=True)
    ex_cfg = ExcitationConfig(max_iter=EXCITATION_ITERATIONS.get(prof.generator_profile, 150), seed=prof.seed)
    traj_file = root / f"excitation-{ctx.robot.name}-{ex_cfg.max_iter}it-seed{prof.seed}.json"
    if traj_file.is_file():
        d = json.loads(traj_file.read_text())
        traj = FourierTrajectory(np.array(d["q0"]), np.array(d["a"]), np.array(d["b"]), float(d["f0"]))
    else:
        ctx.log(f"[bench] designing the excitation trajectory ({ex_cfg.max_iter} IPOPT iterations)")
        traj, report = design_excitation(ctx.robot, ex_cfg)
        ctx.log(f"[bench] excitation: cond {report['condition_start']:.1f} -> {report['condition']:.1f}")
        tmp = traj_file.with_suffix(".partial")
        tmp.write_text(json.dumps(traj.to_dict()))
        tmp.replace(traj_file)
    cfg = scenario_config(ctx.scenario, prof.generator_profile, seed=prof.seed, **prof.generator_overrides)
    ident_dir = root / f"{ctx.scenario}-identification-{cfg.config_hash()}-{traj_file.stem}"
    try:
        ident = load_dataset(ident_dir)
    except DatasetError:
        ctx.log(f"[bench] {ctx.scenario}: simulating the identification run")
        ident = load_dataset(record_excitation_dataset(ident_dir, cfg, traj, n_instances=2, periods=2.0,
                                                       seed=prof.seed, progress=False))
    models = {m: identify(ident, m, ctx.robot, splits=("train",), acceleration="zero-phase")
              for m in ("ols", "consistent", "sigmoid-friction")}
    ctx.cache["identified"] = models
    return models


def _row(task, name, predict_instance, inputs, single=None):
    from .runner import Predictor, RowSpec

    def build(ds, ctx):
        models = _identified(ctx)
        return Predictor(predict=lambda insts: [predict_instance(models, ctx, i) for i in insts],
                         single_call=(lambda inst, k: single(models, ctx, inst, k)) if single else None,
                         inputs=inputs)

    return RowSpec(task, name, "identified", build)


def _identified_robot(models, ctx):
    robot = ctx.cache.get("identified-robot")
    if robot is None:
        robot = ctx.cache["identified-robot"] = models["consistent"].to_robot()
    return robot


def _base_wrench_identified(models, ctx, inst):
    return tip_force_from_base_wrench(_identified_robot(models, ctx), inst.q, inst.qd, inst.qdd, inst.base_wrench)


def _tared_wrench(models, ctx, inst) -> np.ndarray:
    """The run's base wrench tared with the consistent set on its first TARE_SECONDS (cached per run)."""
    key = ("identified-tared-wrench", inst.name)
    if key not in ctx.cache:
        ctx.cache[key] = tared_base_wrench(_identified_robot(models, ctx), inst.q, inst.qd, inst.qdd, inst.base_wrench,
                                           tare_samples(ctx.dataset.meta["record_hz"], TARE_SECONDS))
    return ctx.cache[key]


def _tared_force_identified(models, ctx, inst, k=None):
    """The base-wrench method on the consistent set and the tared sensor: all samples, or sample k."""
    w = _tared_wrench(models, ctx, inst)
    s = slice(None) if k is None else k
    return tip_force_from_base_wrench(_identified_robot(models, ctx), inst.q[s], inst.qd[s], inst.qdd[s], w[s])


def _identified_bw_torque(models, ctx, inst, k=None):
    """tau = identified model (with friction) - J_v^T F_bw: the contact torque taken out with the base sensor."""
    f = _tared_force_identified(models, ctx, inst, k)
    s = slice(None) if k is None else k
    return models["sigmoid-friction"].predict_torque(inst.q[s], inst.qd[s], inst.qdd[s]) \
        - contact_joint_torques(ctx.robot, inst.q[s], f)


def _torque_row(name: str, method: str):
    """A row predicting with one identified model; per call: the same function on one sample."""
    return _row("joint_torque", name, lambda m, c, i: m[method].predict_torque(i.q, i.qd, i.qdd), "q, qd, qdd",
                single=lambda m, c, i, k: m[method].predict_torque(i.q[k], i.qd[k], i.qdd[k]))


def _friction_only(models, ctx, q, qd, qdd):
    return ctx.robot.inverse_dynamics(q, qd, qdd) + models["sigmoid-friction"].friction(qd)


def identified_row_specs(profile) -> list:
    return [
        _torque_row("identified-ols", "ols"),
        _torque_row("identified-consistent", "consistent"),
        _torque_row("identified-sigmoid-friction", "sigmoid-friction"),
        _row("joint_torque", "rnea+identified-friction", lambda m, c, i: _friction_only(m, c, i.q, i.qd, i.qdd),
             "q, qd, qdd", single=lambda m, c, i, k: _friction_only(m, c, i.q[k], i.qd[k], i.qdd[k])),
        _row("tip_force", "base-wrench-identified", _base_wrench_identified, "q, qd, qdd, base_wrench",
             single=lambda m, c, i, k: tip_force_from_base_wrench(_identified_robot(m, c), i.q[k], i.qd[k], i.qdd[k],
                                                                  i.base_wrench[k])),
        _row("tip_force", "base-wrench-identified-tared", _tared_force_identified, TARED_INPUTS,
             single=lambda m, c, i, k: _tared_force_identified(m, c, i, k)),
        _row("joint_torque", "identified-bw-tared", _identified_bw_torque, TARED_INPUTS,
             single=lambda m, c, i, k: _identified_bw_torque(m, c, i, k)),
    ]


TARED_INPUTS = "q, qd, qdd, base_wrench (tared on the first 0.5 s)"
