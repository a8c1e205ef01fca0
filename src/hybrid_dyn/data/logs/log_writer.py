"""Writing an import's dataset: derivatives per segment, instances, splits, manifest, and the swap.

The dataset is built in a run-unique folder beside ``out`` and renamed into place at
the end (:func:`write_dataset`), so an interrupted import leaves any previous dataset
intact; an existing ``out`` is replaced only when it provably holds nothing but a
toolkit dataset (:func:`check_replaceable`).
"""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

from ..data_checks import empty_split_problems
from ...outputs import refuse_foreign, unique_temp
from ..dataset import FIELD_UNITS, package_versions, sha256_file, write_instance, write_manifest
from ..derivatives import differentiate
from .log_validation import Segment
from .import_report import ImportReport
from .log_spec import LogImportError, LogSpec, LogSpecError
from .log_readers import natural_key
from ..splits import split_trajectories

IMPORTER_VERSION = 1  # bump when the importer's algorithm changes what a spec and its logs produce


def _derive(spec: LogSpec, seg: Segment) -> dict:
    """A segment's fields with qd and qdd estimated (:func:`derive_fields`)."""
    return derive_fields(spec, seg.fields, seg.next_qd)


def derive_fields(spec: LogSpec, fields: dict, next_qd=None, dt: float | None = None) -> dict:
    """``fields`` with qd (when not logged, and in a bag's rows whose velocity is empty) and qdd (unless
    logged) estimated (``data/derivatives.py``); ``dt`` [s]: the segment's median step when ``fields`` is a
    block of it."""
    f = dict(fields)
    flt = spec.derivatives
    if "qd" in f and not np.isfinite(f["qd"]).all():  # rows without a logged velocity: qd from q there
        gap = ~np.isfinite(f["qd"]).all(axis=1)
        qd = f["qd"].copy()
        qd[gap] = differentiate(f["q"], f["t"], flt, 1, dt=dt)[gap]
        f["qd"] = qd
    if "qdd" in f:
        if "qd" not in f:
            f["qd"] = differentiate(f["q"], f["t"], flt, 1, dt=dt)
        return f
    if "qd" not in f:
        f["qd"] = differentiate(f["q"], f["t"], flt, 1, dt=dt)
        f["qdd"] = differentiate(f["q"], f["t"], flt, 2, dt=dt)
    else:
        f["qdd"] = differentiate(f["qd"], f["t"], flt, 1, x_next=next_qd, dt=dt)
    return f


# What a dataset folder of the toolkit holds at its top level (generated or imported).
_DATASET_ENTRIES = {"manifest.json", "instances", "import_report.json", "import_report.txt", "generator.json"}


def check_replaceable(out: Path, overwrite: bool) -> None:
    """Refuse an existing ``out`` unless ``overwrite`` and it provably holds only a toolkit dataset.

    The proof is the dataset's own manifest: every file in the folder must be the
    manifest, an import report, or an instance file (or completion record) it lists.
    An empty folder holds nothing to lose.
    """
    if not out.exists() and not out.is_symlink():
        return
    if not overwrite:
        raise LogImportError(f"{out} already exists; pass overwrite=True (CLI: --overwrite) to replace it")
    if out.is_symlink() or not out.is_dir():
        refuse_foreign(out, "dataset", "it is not a folder")
    entries = sorted(p.name for p in out.iterdir())
    if not entries:
        return
    try:
        meta = json.loads((out / "manifest.json").read_text())
        listed = {Path(r["file"]).name for r in meta["instances"]} | {f"{r['name']}.json" for r in meta["instances"]}
        ours = meta.get("format") == "hybrid_dyn.dataset"
    except (OSError, ValueError, KeyError, TypeError):
        ours = False
    if not ours:
        refuse_foreign(out, "dataset", "it has no readable hybrid-dyn manifest.json")
    foreign = [out / e for e in entries if e not in _DATASET_ENTRIES]
    if (out / "instances").is_dir():
        foreign += [p for p in sorted((out / "instances").iterdir()) if p.name not in listed]
    if foreign:
        refuse_foreign(out, "dataset", f"it holds {', '.join(map(str, foreign[:3]))}"
                                       f"{' ...' if len(foreign) > 3 else ''}, which its manifest does not list")


def write_dataset(spec: LogSpec, segments: list, report: ImportReport, out: Path, overwrite: bool) -> None:
    partial = unique_temp(out)  # this run's own build folder: never another's, never the user's
    partial.mkdir(parents=True)
    try:
        _build(spec, segments, report, partial)
        _swap_in(partial, out, overwrite)
    finally:
        if partial.exists():  # an error before the rename: leave nothing of this run behind
            shutil.rmtree(partial)
    report.path = out


def _swap_in(partial: Path, out: Path, overwrite: bool) -> None:
    """Rename the finished ``partial`` to ``out``; a previous dataset there goes to a run-unique backup first."""
    check_replaceable(out, overwrite)  # again: something may have appeared during the import
    if not out.exists():
        os.replace(partial, out)
        return
    old = unique_temp(out, ".old")
    os.replace(out, old)
    os.replace(partial, out)
    shutil.rmtree(old)


def _build(spec: LogSpec, segments: list, report: ImportReport, partial: Path) -> None:
    from tqdm import tqdm

    by_traj = {}
    for seg in segments:
        by_traj.setdefault(seg.trajectory, []).append(seg)
    # The split first: fractions that leave a split empty are refused before any instance is written.
    # Each trajectory's first sample time [s]: the order of a time split (data/splits.py).
    traj_split = trajectory_split(spec, {k: min(float(s.fields["t"][0]) for s in v) for k, v in by_traj.items()})
    records, steps = [], []
    fields_written = None
    for traj in sorted(by_traj, key=natural_key):
        segs = by_traj[traj]
        for k, seg in enumerate(tqdm(segs, desc=f"import {traj}", leave=False, disable=len(segments) < 50)):
            f = _derive(spec, seg)
            name = traj if len(segs) == 1 else f"{traj}_s{k:02d}"
            attrs = {"source": seg.table.source.name, "table": seg.table.name, "trajectory": traj,
                     "first_row": int(seg.rows[0]) + 1, "last_row": int(seg.rows[-1]) + 1}
            sha = write_instance(partial / "instances" / f"{name}.h5", f, attrs=attrs)
            fields_written = sorted(f)
            if len(f["t"]) > 1:
                steps.append(np.diff(f["t"]))
            records.append(instance_record(name, sha, len(f["t"]), attrs))
    step = float(np.median(np.concatenate(steps))) if steps else None
    write_manifest_files(spec, report, partial, records, traj_split, step, fields_written)


def trajectory_split(spec: LogSpec, first_t: dict) -> dict:
    """Trajectories to splits (``data/splits.py``) from each one's first sample time [s]; fractions that leave
    a split empty are refused."""
    traj_split = split_trajectories(spec.split_spec, first_t)
    empty = empty_split_problems(traj_split) if len(first_t) >= 3 else []  # fewer: warned in the manifest
    if empty and spec.split_by == "list":
        raise LogSpecError(f"{spec.name}: {empty[0]}: [split] lists no trajectory for it")
    if empty:
        raise LogSpecError(f"{spec.name}: {empty[0]} ({len(first_t)} trajectories, test_frac = {spec.test_frac}, "
                           f"val_frac = {spec.val_frac} of the rest); choose smaller fractions")
    return traj_split


def instance_record(name: str, sha: str, n: int, attrs: dict) -> dict:
    """The manifest's record of one written instance."""
    return {"name": name, "file": f"instances/{name}.h5", "sha256": sha, "n_samples": n,
            "trajectory": attrs["trajectory"], "source": attrs["source"], "table": attrs["table"],
            "rows": [attrs["first_row"], attrs["last_row"]]}


def write_manifest_files(spec: LogSpec, report: ImportReport, partial: Path, records: list, traj_split: dict,
                         step: float | None, fields_written: list) -> None:
    """The report files and the manifest of the instances ``records`` written in ``partial``; ``step``: the
    median sample step [s] over them."""
    n_traj = sum(len(names) for names in traj_split.values())
    report.instances = len(records)
    if n_traj < 3:
        report.warnings.append(f"only {n_traj} trajectories: all are in the train split "
                               f"(use trajectories from = \"blocks\" to cut one log into several)")
    splits = {s: sorted(r["name"] for r in records if r["trajectory"] in names) for s, names in traj_split.items()}
    estimated = "given" if "qdd" in spec.columns else spec.derivatives.to_dict()
    units = dict(FIELD_UNITS, tau_m="Nm (the logged joint torque)")
    full = report.to_dict()
    (partial / "import_report.json").write_text(json.dumps(full, indent=1))
    (partial / "import_report.txt").write_text(report.text(max_per_kind=10**9) + "\n")
    write_manifest(partial, {
        "robot": spec.robot, "scenario": spec.name, "seed": spec.split_seed,
        "record_hz": (1.0 / step) if step else None,
        "config": {"generator": "import_log", "importer_version": IMPORTER_VERSION, "spec": spec.to_dict(),
                   "notes": spec.notes},
        "fields": {k: units[k] for k in fields_written}, "packages": package_versions(),
        "instances": records, "splits": splits, "trajectory_splits": traj_split,
        "split": {**spec.split_spec.to_dict(), "text": spec.split_spec.describe(n_traj)},
        "import": {**report.summary(), "derivatives": estimated,
                   "velocities": "logged" if "qd" in spec.columns else "estimated",
                   "sources": [{"file": str(f), "sha256": sha256_file(f)} for f in spec.files],
                   "issues_first_100": full["issues"][:100], "report": "import_report.json"},
    })
