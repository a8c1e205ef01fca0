"""Where a replay's rows go as they come (``replay.py``): an MCAP ROS 2 bag or a CSV, written row by row,
and what the figure and the summary need, kept in bounded memory.

- :class:`McapSink`: ``/tip_force`` (``geometry_msgs/msg/WrenchStamped``) and ``/tip_force/status``
  (``std_msgs/msg/String``) by ``rosbags``' writer; each WrenchStamped is serialized once by ``rosbags``
  and the rest are that message with its stamp and numbers put in place (checked against ``rosbags``
  on the first row), each status string once;
- :class:`CsvSink`: ``stamp_ns, t, fx, fy, fz, status`` and the error bar's columns where it has one;
- :class:`Summary`: the status counts, the RMS against a tip sensor over "ok" samples, and every
  sample for the figure while they are few, every 2nd, 4th, ... once they are many (at most
  ``FIGURE_POINTS``), so an hour at 1 kHz plots from about 100 000 points.
"""
from __future__ import annotations

import csv
import struct
from pathlib import Path

import numpy as np

FIGURE_POINTS = 100_000


class Summary:
    """Counts and a thinned copy of the replay for the figure (module docstring)."""

    def __init__(self):
        self.n, self.statuses, self.sq, self.n_ok, self.stride = 0, {}, 0.0, 0, 1
        self.kept = {"t": [], "force": [], "truth": [], "ok": []}
        self.has_truth = True

    def add(self, t: np.ndarray, force: np.ndarray, status: list, truth: np.ndarray | None) -> None:
        for s in status:
            key = s.split(":")[0]
            self.statuses[key] = self.statuses.get(key, 0) + 1
        ok = np.array([s == "ok" for s in status], bool)
        self.has_truth = self.has_truth and truth is not None
        if truth is not None and ok.any():
            self.sq += float(np.sum((force[ok] - truth[ok]) ** 2))
            self.n_ok += int(ok.sum())
        pick = (self.n + np.arange(len(t))) % self.stride == 0
        self.n += len(t)
        if self.has_truth:
            for k, v in (("t", t), ("force", force), ("truth", truth), ("ok", ok)):
                self.kept[k].append(v[pick])
            if sum(len(x) for x in self.kept["t"]) > FIGURE_POINTS:  # twice as sparse from here on
                self.kept = {k: [np.concatenate(v)[::2]] for k, v in self.kept.items()}
                self.stride *= 2

    def rms(self) -> tuple[float, int] | None:
        """RMS [N] against the tip sensor over the "ok" samples and how many; None without either."""
        return (float(np.sqrt(self.sq / self.n_ok)), self.n_ok) if self.has_truth and self.n_ok else None

    def figure_rows(self):
        """(t, force, truth, ok) of the thinned samples, or None without a tip sensor."""
        if not self.has_truth or not self.kept["t"]:
            return None
        return tuple(np.concatenate(self.kept[k]) for k in ("t", "force", "truth", "ok"))


class CsvSink:
    def __init__(self, path: Path):
        self.fh = open(path, "w", newline="")
        self.w, self.header = csv.writer(self.fh), False

    def write(self, stamps_ns, t, force, status, sigma, truth=None) -> None:
        if not self.header:
            extra = [] if sigma is None else (["sigma"] if sigma.shape[1] == 1 else
                                              [f"sigma{j + 1}" for j in range(sigma.shape[1])])
            self.w.writerow(["stamp_ns", "t", "fx", "fy", "fz", "status", *extra])
            self.header = True
        rows = zip(stamps_ns.tolist(), t.tolist(), force.tolist(), status,
                   sigma.tolist() if sigma is not None else [()] * len(t))
        self.w.writerows([s, repr(tt), repr(f[0]), repr(f[1]), repr(f[2]), st, *map(repr, sg)]
                         for s, tt, f, st, sg in rows)

    def close(self) -> None:
        self.fh.close()


class McapSink:
    """A ROS 2 bag (MCAP storage) in the folder ``folder``; its one .mcap file is the output."""

    def __init__(self, folder: Path, frame: str):
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore

        self.store = store = get_typestore(Stores.ROS2_HUMBLE)
        self.writer = Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.wrench = self.writer.add_connection("/tip_force", "geometry_msgs/msg/WrenchStamped", typestore=store)
        self.status = self.writer.add_connection("/tip_force/status", "std_msgs/msg/String", typestore=store)
        self.frame, self.template, self.checked, self.strings = frame, None, False, {}

    def _message(self, stamp: int, f) -> bytes:
        T = self.store.types
        header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
            sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000), frame_id=self.frame)
        msg = T["geometry_msgs/msg/WrenchStamped"](header=header, wrench=T["geometry_msgs/msg/Wrench"](
            force=T["geometry_msgs/msg/Vector3"](x=f[0], y=f[1], z=f[2]),
            torque=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)))
        return bytes(self.store.serialize_cdr(msg, "geometry_msgs/msg/WrenchStamped"))

    def write(self, stamps_ns, t, force, status, sigma, truth=None) -> None:
        for stamp, f, s in zip(stamps_ns.tolist(), force.tolist(), status):
            if self.template is None:
                self.template = bytearray(self._message(0, (0.0, 0.0, 0.0)))
            # CDR: a 4-byte encapsulation header, the stamp (int32 sec, uint32 nanosec), the frame_id, then the
            # six float64 at the end (force, torque).
            raw = self.template
            struct.pack_into("<iI", raw, 4, stamp // 1_000_000_000, stamp % 1_000_000_000)
            struct.pack_into("<3d", raw, len(raw) - 48, *f)
            data = bytes(raw)
            if not self.checked:  # the layout above, checked once against rosbags' own serializer
                if data != self._message(stamp, f):
                    raise RuntimeError("the CDR layout of WrenchStamped is not the one assumed")
                self.checked = True
            self.writer.write(self.wrench, stamp, data)
            if s not in self.strings:
                self.strings[s] = bytes(self.store.serialize_cdr(self.store.types["std_msgs/msg/String"](data=s),
                                                                 "std_msgs/msg/String"))
            self.writer.write(self.status, stamp, self.strings[s])

    def close(self) -> None:
        self.writer.close()


def write_figure(rows, frame: str, method: str, rms, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, force, truth, ok = rows
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 6.5))
    for j, ax in enumerate(axes):
        ax.plot(t, force[:, j], color="C0", lw=0.8, label=f"estimate ({method})")
        ax.plot(t, truth[:, j], color="k", lw=1.0, ls="--", label="tip sensor")  # on top: both show
        ax.fill_between(t, 0, 1, where=~ok, transform=ax.get_xaxis_transform(), color="C1", alpha=0.15,
                        label="status not ok", step="mid")
        ax.set_ylabel(f"F{'xyz'[j]} [N]")
    axes[0].set_title(f"tip force in {frame}" + (f": {rms[0]:.3f} N RMS over {rms[1]} ok samples" if rms else ""))
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("t [s] from the first sample")
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)
