"""Tip force in free motion on the real arms: the streaming estimator on each real log, per torque model.

Nothing touches the tool in the shipped real logs (Panda, KUKA LWR, Baxter), so the true tip force is about
zero and every newton the estimator reads is a phantom. For each log and each torque model:

1. the model is identified on the log's **training** part (``identify``, physically consistent);
2. the estimator is **calibrated** on its **validation** part (``estimator/calibrate.py``: error bars,
   bandwidth, max_sigma), for each joint-torque method;
3. the whole log is replayed through ``hybrid-dyn estimate``'s own code path (``estimator/replay.py``: the
   log's stamps, the spec's encoder model), and the calls on the **test** part are scored: phantom |F| RMS
   and 95th percentile, the share ``ok``, the share of ``ok`` calls whose |F| lies within 2 |sigma|;
4. beside each, the **offline floor**: pinv(J_v^T) of the torque model's residual on the test part (with the
   log's zero-phase qdd), the phantom a joint-torque estimate cannot beat with that model.

Torque models: ``nominal`` (the description's parameters), ``identified`` (the identified inertials alone),
``identified+friction`` (and the declared springs: Baxter's shoulder), ``hybrid`` (that model plus the residual GP of
the bench's ``gp-residual-identified``, fitted on the training part, its hyperparameters chosen on the validation
part, which also calibrates it). :func:`free_motion_rows` returns
the table; ``benchmarks/free_motion.py`` writes it into ``reports/real``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

# The logs (import specs shipped in resources/real) and the joint-torque methods scored on each.
LOGS = ("real-panda", "real-kuka", "real-baxter")
METHODS = ("torques-pinv", "momentum-observer", "kalman-fusion")
# (+springs where the robot declares them; "hybrid": that model plus a residual GP fitted on the training part)
TORQUE_MODELS = ("nominal", "identified", "identified+friction", "hybrid")


@dataclass
class FreeMotionRow:
    """One row of the table: phantom forces [N] on the log's test part."""

    robot: str
    torque_model: str
    method: str
    bandwidth: float
    phantom_rms_N: float
    phantom_p95_N: float
    share_ok: float
    ok_within_2sigma: float
    offline_floor_N: float
    test_calls: int


def rows_in_split(replay, test_instances) -> np.ndarray:
    """Which rows of ``replay`` (``replay_log``'s) lie in the test part: a row of recording r at time t belongs
    to a test instance named r (a trajectory) or r_... (a block of it) whose time span holds t."""
    keep = np.zeros(len(replay.t), bool)
    for inst in test_instances:
        t = np.asarray(inst["t"], float)
        rec = np.array([inst.name == r or inst.name.startswith(f"{r}_") for r in replay.recording])
        keep |= rec & (replay.t >= t[0] - 1e-9) & (replay.t <= t[-1] + 1e-9)
    return keep


def offline_floor(robot, torque_model, instances) -> float:
    """RMS |pinv(J_v^T) e| [N] over ``instances``, e the torque model's residual [Nm] (``torque_residual``)."""
    from ..estimator.calibrate import pinv_jt, torque_residual

    e, _, _ = torque_residual(robot, torque_model, instances)
    f = np.einsum("nij,nj->ni", pinv_jt(robot, instances), e)
    return float(np.sqrt(np.mean(np.sum(f * f, axis=1))))


def score(replay, keep) -> dict:
    """The columns of a row from the replayed test calls."""
    f = replay.force[keep]
    size = np.linalg.norm(f, axis=1)
    status = np.array(replay.status)[keep]
    ok = status == "ok"
    sigma = replay.sigma[keep] if replay.sigma is not None else np.full_like(f, np.inf)
    within = size[ok] <= 2.0 * np.linalg.norm(sigma[ok], axis=1)
    return {"phantom_rms_N": float(np.sqrt(np.mean(size ** 2))), "phantom_p95_N": float(np.percentile(size, 95)),
            "share_ok": float(ok.mean()), "ok_within_2sigma": float(within.mean()) if ok.any() else float("nan"),
            "test_calls": int(keep.sum())}


def free_motion_rows(work: Path, logs=LOGS, methods=METHODS, progress=print) -> list[FreeMotionRow]:
    """The table for ``logs`` x TORQUE_MODELS x ``methods``; ``work``: a folder for the imported logs, the
    identified files and calibrations (each made once: a rerun reuses them, a partial file is never read)."""
    from ..analytic.robot import load_robot
    from ..data import load_dataset
    from ..data.logs.importer import import_log, read_spec
    from ..data.logs.real_logs import real_spec_path
    from ..estimator.calibrate import calibrate
    from ..estimator.calibration import Calibration
    from ..estimator.replay import replay_log
    from ..estimator.torque_model import JointTorqueModel
    from ..identify.identified_model import identify
    from ..learn.gp_residual import train_gp_residual

    work = Path(work)
    rows = []
    for log in logs:
        spec = read_spec(real_spec_path(log))
        data = work / log
        if not (data / "manifest.json").exists():
            progress(f"{log}: importing")
            import_log(spec, data)
        ds = load_dataset(data)
        nominal = load_robot(ds.meta["robot"], num_threads=1)
        identified = work / f"{log}-identified.json"
        if not identified.exists():
            progress(f"{log}: identifying on the training part")
            identify(ds, "consistent", nominal, splits=("train",)).save(identified)
        val, test = ds.split("val"), ds.split("test")
        rate = 1.0 / float(np.median(np.concatenate([np.diff(np.asarray(i["t"], float)) for i in val])))
        for model_name in TORQUE_MODELS:
            params = None if model_name == "nominal" else identified
            robot = load_robot(ds.meta["robot"], params=params, num_threads=1)
            full = None if params is None else JointTorqueModel.from_params(params, robot)
            torque_model, residual = (full if model_name == "identified+friction" else None), None
            if model_name == "identified":  # the inertials alone: the friction and springs stay in tau_J
                torque_model = JointTorqueModel("identified", tuple(robot.joint_names), digest=f"{full.digest}/rigid")
            if model_name == "hybrid":  # the residual GP of the bench's gp-residual-identified, on the same file
                residual = work / f"{log}-gp-residual"
                if not (residual / "config.json").exists():
                    progress(f"{log}: fitting the residual GP on the training part (chosen on validation)")
                train_gp_residual(ds, identified, residual, robot=robot)
                torque_model = full.with_residual_gp(residual, robot)
            floor = offline_floor(robot, torque_model, test)
            label = model_name if torque_model is None else torque_model.name
            cal_file = work / f"{log}-{label}-calibration.json"
            if cal_file.exists():
                cal = Calibration.load(cal_file)
            else:
                progress(f"{log}, {label}: calibrating on the validation part")
                cal = calibrate(robot, methods, val, rate, torque_model=torque_model, encoder_resolution=0.0,
                                before=ds.split("train"),
                                source={"log": log, "split": "val", "params": None if params is None else str(params)})
                cal.save(cal_file)
            for method in methods:
                if method not in cal.methods:
                    progress(f"{log}, {label}, {method}: {cal.source['not_calibrated'][method]}")
                    continue
                replay, _ = replay_log(spec, method, params=params, calibration=cal,
                                       torque_model="params" if residual is not None else torque_model,
                                       residual=residual)
                row = FreeMotionRow(log.removeprefix("real-"), label, method, cal.methods[method].bandwidth,
                                    offline_floor_N=floor, **score(replay, rows_in_split(replay, test)))
                progress(f"{row.robot}, {row.torque_model}, {row.method}: phantom {row.phantom_rms_N:.2f} N RMS "
                         f"(floor {floor:.2f}), ok {100 * row.share_ok:.0f} %, within 2 sigma "
                         f"{100 * row.ok_within_2sigma:.0f} %")
                rows.append(row)
    return rows


def write_table(rows, out: Path) -> tuple[Path, Path]:
    """``free_motion.csv`` and ``free_motion.md`` in ``out`` (the section's table)."""
    import csv

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path, md_path = out / "free_motion.csv", out / "free_motion.md"
    fields = list(FreeMotionRow.__dataclass_fields__)
    with open(csv_path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in asdict(r).items()})
    lines = ["| robot | torque model | method | bandwidth | phantom RMS [N] | p95 [N] | ok | ok within 2 sigma "
             "| offline floor [N] |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.robot} | {r.torque_model} | {r.method} | {r.bandwidth:.3g} | {r.phantom_rms_N:.2f} | "
                     f"{r.phantom_p95_N:.2f} | {100 * r.share_ok:.0f} % | {100 * r.ok_within_2sigma:.0f} % | "
                     f"{r.offline_floor_N:.2f} |")
    md_path.write_text("\n".join(lines) + "\n")
    return csv_path, md_path


SECTION = "## Tip force in free motion"


def section_lines(out: Path) -> list[str]:
    """The README section of ``out`` (a report folder) from its ``free_motion.md``, or [] without one."""
    table = Path(out) / "free_motion.md"
    if not table.exists():
        return []
    return ["", SECTION, "",
            "The streaming estimator (`hybrid-dyn estimate`'s own path: the log's stamps, its encoders) on each real "
            "log's test part, for each torque model and joint-torque method. Nothing touches the tool, so every "
            "newton is a phantom. Each model is identified on the log's training part and the estimator calibrated "
            "on its validation part (`hybrid-dyn calibrate`: error bars, bandwidth, max_sigma); the offline floor is "
            "RMS |pinv(J_v^T) e| of the model's torque residual e on the test part, the phantom of a method that "
            "reads each sample alone (an observer's low-pass goes below it). `ok within 2 sigma`: the share of `ok` "
            "calls whose |F| lies within 2 |sigma|. Written by `python benchmarks/free_motion.py` "
            "(`free_motion.csv`, `free_motion.md`).", "",
            "No row sets a seed tip net trained in simulation on these logs (sim to real): every seed tip net reads "
            "the base force/torque sensor (its inputs are the base wrench, q, qd, qdd and, for some, tau_J), and none "
            "of the three logs has one.", ""] + table.read_text().rstrip("\n").split("\n") + _uncalibrated_lines(out)


UNCALIBRATED = "uncalibrated_free_motion.md"


def _uncalibrated_lines(out: Path) -> list[str]:
    """The section's part on the estimator without a calibration (``benchmarks/uncalibrated_free_motion.py``)."""
    table = Path(out) / UNCALIBRATED
    if not table.exists():
        return []
    return ["", "Without a calibration the error bar's model term is what the robot description states "
            "(`estimator/model_term.py`: the Panda's 10 % on its inertials, and 10 % where a description states none, as "
            "the KUKA LWR's and Baxter's). On the same test parts (`ok within 2 sigma` as above; written by "
            f"`python benchmarks/uncalibrated_free_motion.py`, `{UNCALIBRATED}`):", ""] + \
        table.read_text().rstrip("\n").split("\n")


def insert_section(readme: Path, lines: list[str]) -> None:
    """Put ``lines`` (a section) into ``readme`` in place of its earlier version, else before "## Files"."""
    text = Path(readme).read_text().split("\n")
    body = lines[1:] if lines and lines[0] == "" else lines
    if SECTION in text:
        start = text.index(SECTION)
        end = next((k for k in range(start + 1, len(text)) if text[k].startswith("## ")), len(text))
        text[start:end] = body + [""]
    else:
        at = text.index("## Files") if "## Files" in text else len(text)
        text[at:at] = body + [""]
    Path(readme).write_text("\n".join(text))


__all__ = ["SECTION", "UNCALIBRATED", "FreeMotionRow", "LOGS", "METHODS", "TORQUE_MODELS", "free_motion_rows",
           "insert_section", "offline_floor", "rows_in_split", "score", "section_lines", "write_table"]
