"""A recorded log replayed through the streaming estimator: ``hybrid-dyn estimate`` (``docs/from_a_ros_bag.md``).

:func:`replay_log` reads a log exactly as ``hybrid-dyn import`` would (the same spec, the same checks:
``importer.checked_segments``) and calls :class:`TipForceEstimator` once per kept sample at the log's own
times, as a control loop would have; :func:`write_estimate` writes what came out:

- ``OUT.mcap``: a ROS 2 bag in one MCAP file with ``/tip_force`` (``geometry_msgs/msg/WrenchStamped``: the
  estimate [N] in the robot's base-sensor frame, zero torque, each header stamp the input sample's stamp)
  and ``/tip_force/status`` (``std_msgs/msg/String``: the estimator's status, with the reason of a rejected
  sample), both logged at the input's stamps, for Foxglove, PlotJuggler or ``rosbags``;
- ``OUT.csv``: ``stamp_ns, t, fx, fy, fz, status`` and, when the estimator reports one, its error bar
  (``last_sigma``);
- ``OUT.png`` beside either, where the log has a tip sensor: the estimate against it.

Nothing existing is overwritten: each file is written under a temporary name and linked into place only
if its name is still free.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OutputPathError, UsageError
from ..outputs import unique_temp

OUT_SUFFIXES = (".mcap", ".csv")


@dataclass
class Replay:
    """What the estimator gave on a log, one row per replayed sample.

    stamps_ns: the input samples' stamps [ns] (a bag's header stamps; else t in ns); t [s]; force (n, 3)
    [N] in the base-sensor frame named ``frame``; status: the estimator's status per sample; sigma: its
    error bar per sample (n, k) where it reports one, else None; truth (n, 3) [N]: the log's tip sensor,
    or None; method: the estimator's name; call_hz [Hz]: the rate it ran at (the log's median step)."""

    stamps_ns: np.ndarray
    t: np.ndarray
    force: np.ndarray
    status: list
    sigma: np.ndarray | None
    truth: np.ndarray | None
    frame: str
    method: str
    call_hz: float

    def rms_against_truth(self) -> tuple[float, int] | None:
        """RMS [N] of the estimate's error against the tip sensor over the samples with status "ok", and
        how many they are; None without a tip sensor or an "ok" sample."""
        ok = np.array([s == "ok" for s in self.status])
        if self.truth is None or not ok.any():
            return None
        err = self.force[ok] - self.truth[ok]
        return float(np.sqrt(np.mean(np.sum(err**2, axis=1)))), int(ok.sum())


def replay_log(spec, method: str = "base-momentum", model=None, encoder_resolution="auto") -> tuple[Replay, object]:
    """Replay the log of ``spec`` (a ``LogSpec``) through a ``TipForceEstimator`` (the analytic ``method``,
    or the trained model in folder ``model``); returns the :class:`Replay` and the import report.
    encoder_resolution [rad]: the log's encoders ("auto": the robot description's; 0: exact q and qd)."""
    from ..analytic.robot import load_robot
    from ..data.logs.importer import checked_segments
    from .tip_force_estimator import TipForceEstimator

    segments, report = checked_segments(spec)
    report.instances = len(segments)  # what an import would write: the report's line reads the same
    if any("qd" not in s.fields for s in segments):
        raise UsageError(f"{spec.name}: the log has no joint velocities; the estimator reads them as logged")
    steps = np.concatenate([np.diff(s.fields["t"]) for s in segments])
    hz = 1.0 / float(np.median(steps))  # the estimator runs at the log's own rate
    robot = load_robot(spec.robot)
    # A bad sample is named in its status, never a stop.
    opts = dict(call_hz=hz, on_bad_input="hold", encoder_resolution=encoder_resolution)
    est = (TipForceEstimator.load(model, robot=spec.robot, **opts) if model is not None
           else TipForceEstimator.analytic(robot, method, **opts))
    _check_sensors(est, segments[0].fields, spec.name)
    rows, table = {k: [] for k in ("stamps", "t", "force", "status", "sigma", "truth")}, None
    for seg in sorted(segments, key=lambda s: (str(s.table.source), s.table.name, s.rows[0])):
        if seg.table is not table:  # another recording: another stream
            table = seg.table
            est.reset()
        f = seg.fields
        stamps = getattr(table, "stamps_ns", None)
        rows["stamps"].append(stamps[seg.rows] if stamps is not None else np.round(f["t"] * 1e9).astype(np.int64))
        for k in range(len(f["t"])):
            force = est.estimate_tip_force(f["q"][k], f["qd"][k], base_wrench=_row(f, "base_wrench", k),
                                           tau_J=_row(f, "tau_J" if "tau_J" in f else "tau_m", k), t=f["t"][k])
            status = est.last_status.value
            if est.last_rejection and status == "input rejected":
                status += f": {est.last_rejection}"
            rows["force"].append(force)
            rows["status"].append(status)
            sigma = getattr(est, "last_sigma", None)  # an error bar, where the estimator gives one
            rows["sigma"].append(None if sigma is None else np.atleast_1d(np.asarray(sigma, float)).ravel())
        rows["t"].append(f["t"])
        rows["truth"].append(f.get("tip_force"))
    sig = rows["sigma"]
    sigma = np.array(sig) if sig and all(s is not None and len(s) == len(sig[0]) for s in sig) else None
    truth = np.concatenate(rows["truth"]) if all(x is not None for x in rows["truth"]) else None
    ros = getattr(spec, "ros", None)
    frame = ros.frame if ros is not None and ros.frame else robot.spec.base_sensor_frame  # the bag's name for it
    name = est.method if model is None else f"learned model {Path(model).name}"
    return Replay(np.concatenate(rows["stamps"]), np.concatenate(rows["t"]), np.array(rows["force"]), rows["status"],
                  sigma, truth, frame, name, hz), report


def _check_sensors(est, fields: dict, name: str) -> None:
    """An analytic method whose sensors the log lacks is refused before the replay (it would reject every
    sample); a learned model's inputs are checked by the model itself."""
    method = est.spec
    if method is None:
        return
    have = {"base_wrench": "base_wrench" in fields, "tau_J": "tau_J" in fields or "tau_m" in fields}
    missing = [r for r in method.reads if not have[r]]
    if missing and (not method.any_of or len(missing) == len(method.reads)):
        raise UsageError(f"{name}: method {est.method} reads {' and '.join(method.reads)}; the log has no "
                         f"{' or '.join(missing)} (a ROS spec: [ros] base_wrench, or the effort)")


def _row(fields: dict, key: str, k: int):
    # The log's tau_J, else its logged joint torque tau_m (a JointState's effort: franka_ros publishes the
    # Panda's measured tau_J there). A method reads only what it needs; the rest is never looked at.
    return fields[key][k] if key in fields else None


def check_outputs(out) -> list[Path]:
    """The files ``write_estimate`` would write (the output and its figure); refused, named, if one
    exists or the suffix is not one it writes."""
    out = Path(out)
    if out.suffix not in OUT_SUFFIXES:
        raise UsageError(f"--out {out} must end in {' or '.join(OUT_SUFFIXES)} (an MCAP ROS 2 bag or a CSV)")
    paths = [out, out.with_suffix(".png")]
    for p in paths:
        if p.exists() or p.is_symlink():
            raise OutputPathError(f"{p} already exists; the estimate never overwrites a file: choose another --out")
    return paths


def write_estimate(replay: Replay, out) -> list[Path]:
    """Write ``replay`` to ``out`` (.mcap or .csv) and, with a tip sensor, the figure ``out`` .png; returns
    the files written."""
    out, figure = check_outputs(out)
    writers = [(out, _write_mcap if out.suffix == ".mcap" else _write_csv)]
    if replay.truth is not None:
        writers.append((figure, _write_figure))
    written = []
    for path, write in writers:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = unique_temp(path)
        try:
            write(replay, tmp)
            _link_new(tmp, path)
        finally:
            if tmp.exists():
                tmp.unlink()
        written.append(path)
    return written


def _link_new(tmp: Path, path: Path) -> None:
    try:
        os.link(tmp, path)  # fails if the name was taken meanwhile: nothing of the user's is replaced
    except FileExistsError:
        raise OutputPathError(f"{path} appeared while the estimate was written; it was left as it is") from None


def _write_csv(replay: Replay, path: Path) -> None:
    import csv

    sigma = replay.sigma
    extra = [] if sigma is None else (["sigma"] if sigma.shape[1] == 1 else [f"sigma{j + 1}" for j in range(sigma.shape[1])])
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["stamp_ns", "t", "fx", "fy", "fz", "status", *extra])
        for k in range(len(replay.t)):
            w.writerow([int(replay.stamps_ns[k]), repr(float(replay.t[k])), *map(repr, replay.force[k].tolist()),
                        replay.status[k], *([] if sigma is None else map(repr, sigma[k].tolist()))])


def _write_mcap(replay: Replay, path: Path) -> None:
    """A ROS 2 bag (MCAP storage) written by rosbags in a temporary folder; its one .mcap file is the output."""
    import shutil

    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    folder = unique_temp(path, ".bag")
    try:
        with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            wrench = writer.add_connection("/tip_force", "geometry_msgs/msg/WrenchStamped", typestore=store)
            status = writer.add_connection("/tip_force/status", "std_msgs/msg/String", typestore=store)
            zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
            for stamp, f, s in zip(replay.stamps_ns.tolist(), replay.force.tolist(), replay.status):
                header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                    sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000), frame_id=replay.frame)
                msg = T["geometry_msgs/msg/WrenchStamped"](header=header, wrench=T["geometry_msgs/msg/Wrench"](
                    force=T["geometry_msgs/msg/Vector3"](x=f[0], y=f[1], z=f[2]), torque=zero))
                writer.write(wrench, stamp, store.serialize_cdr(msg, "geometry_msgs/msg/WrenchStamped"))
                writer.write(status, stamp, store.serialize_cdr(T["std_msgs/msg/String"](data=s), "std_msgs/msg/String"))
        os.replace(folder / f"{folder.name}.mcap", path)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _write_figure(replay: Replay, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = np.array([s == "ok" for s in replay.status])
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 6.5))
    for j, ax in enumerate(axes):
        ax.plot(replay.t, replay.force[:, j], color="C0", lw=0.8, label=f"estimate ({replay.method})")
        ax.plot(replay.t, replay.truth[:, j], color="k", lw=1.0, ls="--", label="tip sensor")  # on top: both show
        ax.fill_between(replay.t, 0, 1, where=~ok, transform=ax.get_xaxis_transform(), color="C1", alpha=0.15,
                        label="status not ok", step="mid")
        ax.set_ylabel(f"F{'xyz'[j]} [N]")
    rms = replay.rms_against_truth()
    axes[0].set_title(f"tip force in {replay.frame}" + (f": {rms[0]:.3f} N RMS over {rms[1]} ok samples" if rms else ""))
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("t [s] from the first sample")
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)
