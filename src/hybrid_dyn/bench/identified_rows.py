"""Identified-model rows of the benchmark: the strongest analytic
baseline, and the residual nets on it.

The design in full: ``docs/design/bench.md`` (identified_rows.py).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import re
import time
from pathlib import Path

import numpy as np

from ..analytic.tare import TARE_SECONDS, tare_samples, tared_base_wrench
from ..analytic.tip_force import contact_joint_torques, tip_force_from_base_wrench
from ..data import DatasetError, load_dataset
from ..outputs import unique_temp
from .learned_rows import gp_predictor, learned_predictor
from .rows import ROWS, Predictor, Row, prior_kept_text

EXCITATION_ITERATIONS = {"quick": 30, "default": 150, "paper": 150}
LOG_SPLITS = ("train", "val")  # what an imported log's identification sees; never its test split
RESIDUAL_PRIOR_METHOD = "consistent"  # the identified model the residual rows sit on
RESIDUAL_ROWS = {"residual-rnea-identified": "residual-rnea", "residual-rnea-bw-identified": "residual-rnea-bw"}
# Rows whose model the bench fits ahead in its own process while it waits for the residual nets' worker
# (runner._score_rows): the fit is saved to the work dir, and the row's build reads it back when scored.
FIT_WHILE_WAITING = ("gp-residual-identified",)


def has_simulated_plant(ds) -> bool:
    """Whether the dataset was simulated on one of :data:`~hybrid_dyn.sim.scenarios.SCENARIOS`'
    plants, on which an excitation run can be recorded (an imported log has none)."""
    from ..sim.scenarios import SCENARIOS

    return ds.meta.get("generator_version") is not None and ds.meta.get("scenario") in SCENARIOS


def file_safe_name(name: str) -> str:
    """``name`` as a file-name part: itself when plain (``panda``), else its safe characters and a
    digest (``panda[tool=none]`` -> ``panda_tool_none_-1c2b...``), so that variants never share a file."""
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", name)
    return safe if safe == name else f"{safe}-{hashlib.sha256(name.encode()).hexdigest()[:8]}"


def fit_needs(ds) -> tuple:
    """What an identified row needs of ``ds`` beyond its own fields: on a dataset with no simulated
    plant the parameters are fitted on its own train + val splits, whose motor torques the fit reads."""
    return () if has_simulated_plant(ds) else ("q", "qd", "qdd", "tau_m")


def _identification_data(ctx) -> tuple:
    """(dataset, identify() keywords, what it is): what this scenario's parameters are fitted on."""
    if "identification-data" not in ctx.cache:
        if has_simulated_plant(ctx.dataset):
            ident = _excitation_dataset(ctx)
            ctx.cache["identification-data"] = (ident, dict(splits=("train",), acceleration="zero-phase"),
                                                f"the excitation run {Path(ident.path).name}")
        else:
            # The CLI's defaults (identify/cli.py): train + val, the logged qdd.
            ctx.cache["identification-data"] = (ctx.dataset, dict(splits=LOG_SPLITS, acceleration="measured"),
                                                "the dataset's train + val splits")
    return ctx.cache["identification-data"]


def _identified(ctx, method: str):
    """(IdentifiedModel, its file) of this scenario for ``method``: fitted once, then read from the work dir."""
    key = ("identified", method)
    if key in ctx.cache:
        return ctx.cache[key]
    from ..identify.least_squares import ConsistentConfig
    from ..identify.identified_model import IdentifiedModel, identify

    data, kwargs, what = _identification_data(ctx)
    robot = ctx.robot
    digest = hashlib.sha256(json.dumps(
        {"data": data.checksum, "robot": robot.name, "params": robot.params_name, "method": method,
         "config": dataclasses.asdict(ConsistentConfig()), **kwargs}, sort_keys=True, default=str).encode()).hexdigest()
    path = Path(ctx.work_dir) / "identified" / f"{method}-{digest[:16]}.json"
    cpu0 = time.process_time()
    if path.is_file():
        model = IdentifiedModel.load(path, robot=robot)
    else:
        ctx.log(f"[bench] {ctx.scenario}: identifying ({method}) on {what}")
        model = identify(data, method, robot, **kwargs)
        model.save(path)
    ctx.cache[key] = (model, path)
    # The fit's CPU [s], claimed by the first row that reads this model (``_row``), whenever it was fitted.
    ctx.cache[("fit-cpu", method)] = time.process_time() - cpu0
    return ctx.cache[key]


class _Models:
    """method -> IdentifiedModel of this scenario, each fitted when a row first asks for it."""

    def __init__(self, ctx):
        self.ctx = ctx

    def __getitem__(self, method: str):
        return _identified(self.ctx, method)[0]


def _excitation_dataset(ctx):
    """The identification run on the scenario's plant (designed and simulated once, cached in the data root)."""
    from ..identify.excitation import ExcitationConfig, FourierTrajectory, design_excitation
    from ..identify.experiment import record_excitation_dataset

    prof = ctx.profile
    root = Path(ctx.data_root)
    root.mkdir(parents=True, exist_ok=True)
    ex_cfg = ExcitationConfig(max_iter=EXCITATION_ITERATIONS.get(prof.generator_size, 150), seed=prof.seed)
    traj_file = root / f"excitation-{file_safe_name(ctx.robot.name)}-{ex_cfg.max_iter}it-seed{prof.seed}.json"
    if traj_file.is_file():
        d = json.loads(traj_file.read_text())
        traj = FourierTrajectory(np.array(d["q0"]), np.array(d["a"]), np.array(d["b"]), float(d["f0"]))
    else:
        ctx.log(f"[bench] designing the excitation trajectory ({ex_cfg.max_iter} IPOPT iterations)")
        traj, report = design_excitation(ctx.robot, ex_cfg)
        ctx.log(f"[bench] excitation: cond {report['condition_start']:.1f} -> {report['condition']:.1f}")
        tmp = unique_temp(traj_file)
        tmp.write_text(json.dumps(traj.to_dict()))
        tmp.replace(traj_file)
    cfg = ctx.plan.generator_config(ctx.source or ctx.scenario, ctx.dataset)  # a --data dataset: its manifest's
    ident_dir = root / f"{ctx.scenario}-identification-{cfg.config_hash()}-{traj_file.stem}"
    try:
        ident = load_dataset(ident_dir)
    except DatasetError:
        ctx.log(f"[bench] {ctx.scenario}: simulating the identification run")
        ident = load_dataset(record_excitation_dataset(ident_dir, cfg, traj, n_instances=2, periods=2.0,
                                                       seed=prof.seed, progress=False))
    return ident


def review(ctx, methods) -> tuple[list[str], list[str]]:
    """(problems, notes) of the identified models ``methods`` a row predicts with (``Predictor.review``):
    each body outside the robot's bounds (``identify.plausibility``; the row is then marked implausible),
    and what the identification data could not determine (a joint under the range of motion, the
    condition number). Computed from the parameters and the data, so a fit cached before the checks is
    checked too."""
    from ..identify.plausibility import fit_warnings

    problems = [f"identified-{m} parameters outside the robot's bounds: {b}"
                for m in methods for b in _identified(ctx, m)[0].implausible_bodies()]
    if "identification-warnings" not in ctx.cache:
        data, kwargs, what = _identification_data(ctx)
        q = np.concatenate([np.asarray(i["q"]) for s in kwargs["splits"] for i in data.split(s)])
        cond = _identified(ctx, methods[0])[0].fit.get("condition_number", float("nan"))  # the same data, any method
        ctx.cache["identification-warnings"] = fit_warnings(q, float(cond), ctx.robot.joint_names, what)
    return problems, list(ctx.cache["identification-warnings"])


def _row(task, name, needs, predict_instance, inputs, single=None, methods=("consistent",)) -> Row:
    """Declare an identified row: predict_instance(models, ctx, inst) and single(models, ctx, inst, k);
    ``methods``: the identified models it predicts with, fitted when it is built (its training, not its
    scoring) and their parameters checked (``review``)."""
    def build(ds, ctx):
        models = _Models(ctx)
        for method in methods:
            models[method]
        # Each fit's CPU goes to the first row that reads it (a fit made before, for the residual nets, too).
        cpu = sum(ctx.cache.pop(("fit-cpu", method), 0.0) for method in methods)
        return Predictor(predict=lambda insts: [predict_instance(models, ctx, i) for i in insts],
                         single_call=(lambda inst, k: single(models, ctx, inst, k)) if single else None,
                         inputs=inputs, review=lambda: review(ctx, methods), train_cpu_seconds=cpu)

    return ROWS.register(Row(name, task, "identified", needs=needs, needs_urdf=True, build=build, more_needs=fit_needs))


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
    return _row("joint_torque", name, TORQUE_NEEDS, lambda m, c, i: m[method].predict_torque(i.q, i.qd, i.qdd),
                "q, qd, qdd", single=lambda m, c, i, k: m[method].predict_torque(i.q[k], i.qd[k], i.qdd[k]),
                methods=(method,))


def _friction_only(models, ctx, q, qd, qdd):
    return ctx.robot.inverse_dynamics(q, qd, qdd) + models["sigmoid-friction"].friction(qd)


def residual_training(ctx, name: str, base_config) -> tuple:
    """(TrainConfig, model folder) of the residual row ``name`` on this scenario's identified model (fitted
    here if not yet): ``base_config`` with the parameter file as the prior's, the folder named by the file's
    content, so that a refit never meets a model of the old one. The runner uses it to train these nets in a
    worker while the bench's process fits the rest (``runner._train_learned_rows``)."""
    _, path = _identified(ctx, RESIDUAL_PRIOR_METHOD)
    config = dataclasses.replace(base_config, analytic_params=str(Path(path).resolve()))
    return config, Path(ctx.work_dir) / "models" / f"{name}-{hashlib.sha256(Path(path).read_bytes()).hexdigest()[:12]}"


def _residual_row(name: str, preset: str) -> Row:
    """A residual net (``preset``) on the identified model, inertials and friction, trained like the learned rows."""
    from ..learn.presets import PRESETS

    def build(ds, ctx):
        from ..learn import train_model

        config, out = residual_training(ctx, name, ctx.plan.train_config())
        t0 = time.perf_counter()
        # the profile's preset_overrides (a study's capacity arm) apply here as to every trained preset row
        model = train_model(ds, ctx.plan.preset(preset), out, config=config, wait=True)  # shared runs/: wait
        train_seconds = getattr(model, "train_seconds", None) or (time.perf_counter() - t0)
        # A learned row: its curve is reported, its single call is the user's (learned_rows.py).
        pred = learned_predictor(model, train_seconds, inputs=", ".join(model.config.get("inputs", []))
                                 + f"; prior on identified-{RESIDUAL_PRIOR_METHOD} (inertials + friction)")
        pred.review = lambda: review(ctx, (RESIDUAL_PRIOR_METHOD,))  # a net on absurd parameters is marked too
        return pred

    p = PRESETS.lookup(preset)
    return ROWS.register(Row(name, "joint_torque", "identified", needs=tuple(p.inputs) + tuple(p.targets), needs_urdf=True,
                       build=build, trains=True, more_needs=fit_needs,
                       # No row is the rnea-bw prior on the consistent set (identified-bw-tared sits on
                       # sigmoid-friction): the report compares only rows whose prior is a row.
                       prior_row=f"identified-{RESIDUAL_PRIOR_METHOD}" if p.prior == "rnea" else None))


def _gp_residual_row(name: str) -> Row:
    """A sparse GP on the residual of the identified model, inertials and friction (learn/gp_residual.py)."""
    def build(ds, ctx):
        from ..learn.gp_residual import GPResidualConfig, train_gp_residual

        _, path = _identified(ctx, RESIDUAL_PRIOR_METHOD)
        config = GPResidualConfig(seed=ctx.profile.seed)
        # Named by the prior file's content and the config: a refit or a new config never meets an old model.
        key = hashlib.sha256(Path(path).read_bytes() + json.dumps(config.to_dict(), sort_keys=True).encode())
        out = Path(ctx.work_dir) / "models" / f"{name}-{key.hexdigest()[:12]}"
        t0 = time.perf_counter()
        model = train_gp_residual(ds, path, out, config, robot=ctx.robot)
        kept = [j + 1 for j, k in enumerate(model.kept_prior) if k]
        ctx.log(f"[bench] {ctx.scenario} {name}: validation RMSE {model.config['val_rmse']:.4f} Nm against the "
                f"prior's {model.config['val_rmse_prior']:.4f}; joints keeping the prior: {kept or 'none'}")
        return gp_predictor(model, t0, prior_kept=prior_kept_text(model.kept_prior),
                            inputs=f"q, qd, qdd; prior on identified-{RESIDUAL_PRIOR_METHOD} (inertials + friction)",
                            review=lambda: review(ctx, (RESIDUAL_PRIOR_METHOD,)))

    return ROWS.register(Row(name, "joint_torque", "identified", needs=TORQUE_NEEDS, needs_urdf=True, build=build,
                       more_needs=fit_needs, prior_row=f"identified-{RESIDUAL_PRIOR_METHOD}"))


# ------------------------------------------------------------------ the rows
TORQUE_NEEDS = ("q", "qd", "qdd", "tau_m")
TIP_NEEDS = ("q", "qd", "qdd", "base_wrench", "tip_force")
TARED_INPUTS = "q, qd, qdd, base_wrench (tared on the first 0.5 s)"

_torque_row("identified-ols", "ols")
_torque_row("identified-consistent", "consistent")
_torque_row("identified-sigmoid-friction", "sigmoid-friction")
# The friction of sigmoid-friction was fitted jointly with its inertials: absurd bodies, suspect friction.
_row("joint_torque", "rnea+identified-friction", TORQUE_NEEDS, lambda m, c, i: _friction_only(m, c, i.q, i.qd, i.qdd),
     "q, qd, qdd", single=lambda m, c, i, k: _friction_only(m, c, i.q[k], i.qd[k], i.qdd[k]),
     methods=("sigmoid-friction",))
_row("tip_force", "base-wrench-identified", TIP_NEEDS, _base_wrench_identified, "q, qd, qdd, base_wrench",
     single=lambda m, c, i, k: tip_force_from_base_wrench(_identified_robot(m, c), i.q[k], i.qd[k], i.qdd[k],
                                                          i.base_wrench[k]), methods=("consistent",))
_row("tip_force", "base-wrench-identified-tared", TIP_NEEDS, _tared_force_identified, TARED_INPUTS,
     single=lambda m, c, i, k: _tared_force_identified(m, c, i, k), methods=("consistent",))
_row("joint_torque", "identified-bw-tared", ("q", "qd", "qdd", "base_wrench", "tau_m"), _identified_bw_torque,
     TARED_INPUTS, single=lambda m, c, i, k: _identified_bw_torque(m, c, i, k),
     methods=("sigmoid-friction", "consistent"))
for _name, _preset in RESIDUAL_ROWS.items():
    _residual_row(_name, _preset)
_gp_residual_row("gp-residual-identified")
