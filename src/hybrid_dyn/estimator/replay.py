"""A recorded log replayed through the streaming estimator: ``hybrid-dyn estimate`` (``docs/from_a_ros_bag.md``).

:func:`estimate_to` reads a log as ``hybrid-dyn import`` would (the same spec, the same row checks; a ROS
bag chunk by chunk, ``data/logs/bag_checks.py``, anything else through ``importer.checked_segments``) and
calls :class:`TipForceEstimator` once per kept sample at the log's own times, as a control loop would have,
writing what comes out as it comes (``replay_sinks.py``): memory is bounded by a chunk, not by the log.
Where a bag's velocity is missing, qd is derived from q (``_fill_qd``). :func:`replay_log` keeps the
replay in memory instead (:class:`Replay`, :func:`write_estimate`). What it writes:

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

import copy
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..analytic.methods import DEFAULT_METHOD
from ..errors import OutputPathError, UsageError
from ..outputs import unique_temp
from .replay_sinks import CsvSink, McapSink, Summary, write_figure

OUT_SUFFIXES = (".mcap", ".csv")


@dataclass
class Replay:
    """What the estimator gave on a log, one row per replayed sample.

    stamps_ns: the input samples' stamps [ns] (a bag's header stamps; else t in ns); t [s]; force (n, 3)
    [N] in the base-sensor frame named ``frame``; status: the estimator's status per sample; sigma: its
    error bar per sample (n, k) where it reports one, else None; truth (n, 3) [N]: the log's tip sensor,
    or None; method: the estimator's name; call_hz [Hz]: the rate it ran at (the log's median step);
    recording: each row's recording's name (a log's table, as its dataset's instances are named after it)."""

    stamps_ns: np.ndarray
    t: np.ndarray
    force: np.ndarray
    status: list
    sigma: np.ndarray | None
    truth: np.ndarray | None
    frame: str
    method: str
    call_hz: float
    recording: np.ndarray | None = None  # (n,) the name of each row's recording (a log's table, a bag's file)

    def rms_against_truth(self) -> tuple[float, int] | None:
        """RMS [N] of the estimate's error against the tip sensor over the samples with status "ok", and
        how many they are; None without a tip sensor or an "ok" sample."""
        ok = np.array([s == "ok" for s in self.status])
        if self.truth is None or not ok.any():
            return None
        err = self.force[ok] - self.truth[ok]
        return float(np.sqrt(np.mean(np.sum(err**2, axis=1)))), int(ok.sum())


def replay_log(spec, method: str = DEFAULT_METHOD, model=None, encoder_resolution=None,
               keep_partial: bool = False, params=None, calibration=None, torque_model="params", residual=None) -> tuple[Replay, object]:
    """Replay the log of ``spec`` (a ``LogSpec``) through a ``TipForceEstimator`` (the analytic ``method``,
    or the trained model in folder ``model``); returns the :class:`Replay` in memory and the import report.
    encoder_resolution [rad]: the log's encoders (None: the spec's ``[encoders]``; "auto": the robot
    description's; 0: q and qd as the arm gives them). params, calibration: the torque model (an identified
    parameter file) and its calibration on this arm (``TipForceEstimator.analytic``); torque_model: what tau_J holds
    beyond the rigid body, where not the params file's (a ``JointTorqueModel``, or None: nothing).
    A long log is better replayed by :func:`estimate_to`, which writes as it goes."""
    keep = _Collect()
    summary, report, info = _replay(spec, [keep], method, model, encoder_resolution, keep_partial,
                                    params=params, calibration=calibration, torque_model=torque_model,
                                    residual=residual)
    return keep.replay(summary, info), report


def estimate_to(spec, out, method: str = DEFAULT_METHOD, model=None, encoder_resolution=None,
                keep_partial: bool = False, progress: bool = True, params=None, calibration=None, residual=None):
    """Replay the log of ``spec`` and write the estimate to ``out`` (.mcap or .csv) as it is made, and the
    figure ``out`` .png where the log has a tip sensor: memory is bounded by a chunk of the log (a bag's
    rows, ``data/logs/bag_checks.py``), not by its length. Returns (:class:`Summary`, the import report,
    the files written, {"method", "call_hz", "frame"})."""
    out, figure = check_outputs(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = unique_temp(out, ".bag" if out.suffix == ".mcap" else "")
    sink = None
    try:
        info_frame = _frame(spec)
        sink = McapSink(tmp, info_frame) if out.suffix == ".mcap" else CsvSink(tmp)
        summary, report, info = _replay(spec, [sink], method, model, encoder_resolution, keep_partial, progress,
                                        params=params, calibration=calibration, residual=residual)
        sink.close()
        sink = None
        _link_new(tmp / f"{tmp.name}.mcap" if out.suffix == ".mcap" else tmp, out)
        written = [out]
        rows = summary.figure_rows()
        if rows is not None:
            written.append(_write_new(figure, lambda p: write_figure(rows, info["frame"], info["method"],
                                                                     summary.rms(), p)))
        return summary, report, written, info
    finally:
        if sink is not None:
            try:
                sink.close()
            except Exception:  # the run failed already: its error is the one to see
                pass
        shutil.rmtree(tmp, ignore_errors=True) if tmp.is_dir() else tmp.unlink(missing_ok=True)


def _frame(spec) -> str:
    """The name the output gives the base-sensor frame: the bag's own where the spec names it."""
    from ..description import resolve_robot

    ros = getattr(spec, "ros", None)
    if ros is not None and ros.frame:
        return ros.frame
    ref = resolve_robot(spec.robot)
    return ref.spec.base_sensor_frame if ref.described else "base"


def _replay(spec, sinks, method, model, encoder_resolution, keep_partial, progress=False, params=None,
            calibration=None, torque_model="params", residual=None):
    """Every kept row of the log through one estimator, block by block, into ``sinks``."""
    from ..analytic.robot import load_robot
    from ..data.logs.import_report import ImportReport
    from .tip_force_estimator import TipForceEstimator

    spec = copy.copy(spec)  # a bag without efforts leaves its torque columns: the caller's spec stays
    report = ImportReport(spec.name)
    blocks = _bag_blocks(spec, report, keep_partial) if spec.ros is not None else _segment_blocks(spec, report)
    est, source, carry, summary = None, None, None, Summary()
    bar = _progress(spec, progress)
    try:
        for src, stamps, f, starts, hz in blocks:
            if est is None:
                if params is not None and model is not None:
                    raise UsageError("params= is the analytic methods' torque model; a trained model brings its own")
                robot = load_robot(spec.robot, params=params, num_threads=1)
                # A bad sample is named in its status, never a stop.
                res = spec.encoder_resolution if encoder_resolution is None else encoder_resolution
                opts = dict(call_hz=hz, on_bad_input="hold", encoder_resolution=res)
                est = (TipForceEstimator.load(model, robot=spec.robot, **opts) if model is not None
                       else TipForceEstimator.analytic(robot, method, params=params, calibration=calibration,
                                                       torque_model=torque_model, residual=residual, **opts))
                _check_sensors(est, f, spec.name)
                info = {"method": est.method if model is None else f"learned model {Path(model).name}",
                        "call_hz": hz, "frame": _frame(spec)}
            if src != source:  # another recording: another stream
                source, carry = src, None
                est.reset()
            carry = _fill_qd(f, starts, carry)
            force, status, sigma = _run(est, f, starts)
            for sink in sinks:
                if isinstance(sink, _Collect):
                    sink.recording.append(np.full(len(stamps), src[-1] if isinstance(src, tuple) else str(src)))
                sink.write(stamps, f["t"], force, status, sigma, f.get("tip_force"))
            summary.add(f["t"], force, status, f.get("tip_force"))
            bar.update(len(stamps))
    finally:
        bar.close()
    if spec.ros is not None:
        _refuse_as_an_import(spec, report)
    return summary, report, info


def _progress(spec, show: bool):
    """A progress bar over a bag's joint-state messages, on long bags only."""
    from tqdm import tqdm

    total = 0
    if show and spec.ros is not None:
        from ..data.logs.bag_stream import open_reader

        for f in spec.files:
            reader = open_reader(Path(f))
            try:
                info = reader.topics.get(spec.ros.joint_states)
                total += info.msgcount if info is not None else 0
            finally:
                reader.close()
    return tqdm(total=total, unit="msg", desc="estimate", disable=total < 200_000, mininterval=2.0)


def _bag_blocks(spec, report, keep_partial):
    from ..data.logs.bag_checks import checked_chunks

    hz = None
    for rows in checked_chunks(spec, report, keep_partial):
        if hz is None:  # the estimator runs at the log's own rate: the median step of its first chunk
            steps = np.diff(rows.fields["t"])
            hz = 1.0 / float(np.median(steps)) if len(steps) else 1.0
        yield rows.source, rows.stamps_ns, rows.fields, rows.starts, hz


def _segment_blocks(spec, report):
    """A log that is no bag: read whole by the importer, then one block per kept segment."""
    from ..data.logs.importer import checked_segments

    segments, checked = checked_segments(spec, derivatives=False)
    report.__dict__.update(checked.__dict__)
    report.instances = len(segments)  # what an import would write: the report's line reads the same
    steps = np.concatenate([np.diff(s.fields["t"]) for s in segments])
    hz = 1.0 / float(np.median(steps))
    for seg in sorted(segments, key=lambda s: (str(s.table.source), s.table.name, s.rows[0])):
        stamps = getattr(seg.table, "stamps_ns", None)
        stamps = stamps[seg.rows] if stamps is not None else np.round(seg.fields["t"] * 1e9).astype(np.int64)
        starts = np.zeros(len(seg.rows), bool)
        starts[0] = True
        yield (str(seg.table.source), seg.table.name), stamps, dict(seg.fields), starts, hz


def _refuse_as_an_import(spec, report) -> None:
    """The refusals of ``importer.checked_segments``, after a streamed read: too many rows dropped, none kept."""
    from ..data.logs.importer import LogImportError, TooManyRowsDroppedError

    frac = report.rows_dropped / max(report.rows_read, 1)
    if frac > spec.checks.max_drop_fraction:
        raise TooManyRowsDroppedError(
            f"{spec.name}: {report.rows_dropped} of {report.rows_read} rows ({100 * frac:.1f} %) failed validation, "
            f"more than max_drop_fraction = {spec.checks.max_drop_fraction}.\n{report.text(5)}")
    if not report.rows_kept:
        raise LogImportError(f"{spec.name}: no usable rows\n{report.text(5)}")


def _fill_qd(f: dict, starts: np.ndarray, carry):
    """qd from q where the log's velocity is missing: the backward difference (the forward one at a
    segment's first row; 0 for a segment of one row). ``carry``: the previous block's last (q, t) when
    its segment goes on here. Returns this block's carry."""
    q, t = f["q"], f["t"]
    if "qd" not in f:
        f["qd"] = np.full_like(q, np.nan)
    gap = ~np.isfinite(f["qd"]).all(axis=1)
    if gap.any():
        nan = np.full((1, q.shape[1]), np.nan)
        first = carry if carry is not None and not starts[0] else (nan, np.nan)
        q_prev, t_prev = np.r_[first[0], q[:-1]], np.r_[first[1], t[:-1]]
        q_prev[starts & (np.arange(len(t)) > 0)] = np.nan
        with np.errstate(invalid="ignore", divide="ignore"):
            back = (q - q_prev) / (t - t_prev)[:, None]
        fwd = np.r_[back[1:], nan]
        fwd[np.r_[starts[1:], True]] = np.nan  # the next row is in another segment
        qd = np.where(np.isfinite(back), back, np.where(np.isfinite(fwd), fwd, 0.0))
        f["qd"] = np.where(gap[:, None], qd, f["qd"])
    return q[-1:], t[-1]


def _run(est, f: dict, starts=None):
    """The estimator on every row of a block: (force (n, 3) [N], statuses, sigma (n, k) or None).

    A segment that starts (``starts``, as the import splits a trajectory) where the time starts anew, or after a
    gap longer than the estimator bridges, is a new stream (``reset``), as the import makes it a new instance; a
    short gap goes on in the same stream (bridged)."""
    n = len(f["t"])
    force, status, sig = np.zeros((n, 3)), [], []
    tau_key = "tau_J" if "tau_J" in f else "tau_m"
    wrench, tau = f.get("base_wrench"), f.get(tau_key)
    q, qd, t = f["q"], f["qd"], f["t"]
    for k in range(n):
        if starts is not None and starts[k] and est.last_t is not None and not est.continues(t[k]):
            est.reset()
        force[k] = est.estimate_tip_force(q[k], qd[k], base_wrench=None if wrench is None else wrench[k],
                                          tau_J=None if tau is None else tau[k], t=t[k])
        s = est.last_status.value
        if est.last_rejection and s == "input rejected":
            s += f": {est.last_rejection}"
        status.append(s)
        sigma = getattr(est, "last_sigma", None)  # an error bar, where the estimator gives one
        sig.append(None if sigma is None else np.atleast_1d(np.asarray(sigma, float)).ravel())
    sigma = np.array(sig) if sig and all(x is not None and len(x) == len(sig[0]) for x in sig) else None
    return force, status, sigma


class _Collect:
    """A sink that keeps everything: the in-memory :class:`Replay`."""

    def __init__(self):
        self.parts = {k: [] for k in ("stamps", "t", "force", "status", "sigma", "truth")}
        self.recording = []  # the name of the recording (a log's table, a bag) of each row

    def write(self, stamps_ns, t, force, status, sigma, truth=None) -> None:
        for k, v in (("stamps", stamps_ns), ("t", t), ("force", force), ("sigma", sigma), ("truth", truth)):
            self.parts[k].append(v)
        self.parts["status"] += status

    def replay(self, summary, info) -> Replay:
        p = self.parts
        sigma = np.concatenate(p["sigma"]) if p["sigma"] and all(s is not None for s in p["sigma"]) else None
        truth = np.concatenate(p["truth"]) if all(x is not None for x in p["truth"]) else None
        return Replay(np.concatenate(p["stamps"]), np.concatenate(p["t"]), np.concatenate(p["force"]), p["status"],
                      sigma, truth, info["frame"], info["method"], info["call_hz"], np.concatenate(self.recording))


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

    def data(path):
        sink = McapSink(path, replay.frame) if out.suffix == ".mcap" else CsvSink(path)
        sink.write(replay.stamps_ns, replay.t, replay.force, replay.status, replay.sigma)
        sink.close()

    written = [_write_new(out, data, folder=out.suffix == ".mcap")]
    if replay.truth is not None:
        ok = np.array([s == "ok" for s in replay.status])
        rows = (replay.t, replay.force, replay.truth, ok)
        written.append(_write_new(figure, lambda p: write_figure(rows, replay.frame, replay.method,
                                                                 replay.rms_against_truth(), p)))
    return written


def _write_new(path: Path, write, folder: bool = False) -> Path:
    """``write(tmp)`` then ``tmp`` linked to ``path`` if that name is still free (a bag: the .mcap in the
    folder ``tmp``)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = unique_temp(path, ".bag" if folder else "")
    try:
        write(tmp)
        _link_new(tmp / f"{tmp.name}.mcap" if folder else tmp, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True) if tmp.is_dir() else tmp.unlink(missing_ok=True)
    return path


def _link_new(tmp: Path, path: Path) -> None:
    try:
        os.link(tmp, path)  # fails if the name was taken meanwhile: nothing of the user's is replaced
    except FileExistsError:
        raise OutputPathError(f"{path} appeared while the estimate was written; it was left as it is") from None
