"""Importing real robot logs into the toolkit's dataset format.

The detail (what it computes, the equations, why each choice): docs/design/data.md, section ``data/logs/importer.py``.
"""
from __future__ import annotations

import copy
import hashlib
import json
import re
from pathlib import Path

from ...outputs import output_lock
from ..dataset import sha256_file
from .log_validation import refuse_as_import, validate_log
# The importer's public names, by concept: the spec, the report, the checks, the writer.
from .import_report import DROP_KINDS, SPLIT_KINDS, ImportReport, RowIssue  # noqa: F401
from .log_spec import (  # noqa: F401
    ANGLE_SIGNALS, JOINT_SIGNALS, SIGNALS, TIME_UNITS, TRAJECTORY_MODES, LogImportError, LogSpec, LogSpecError,
    MissingColumnError, StrictImportError, TooManyRowsDroppedError, ValidationChecks, read_spec, spec_from_dict,
)
from .log_writer import IMPORTER_VERSION, check_replaceable, write_dataset


def import_log(source, out, *, overwrite: bool = False, strict: bool = False, keep_partial: bool = False,
               **spec_args) -> ImportReport:
    """Import a robot log into a dataset at ``out``; returns the :class:`ImportReport`.

    ``source``: a TOML spec path (``.toml``), a :class:`LogSpec`, or the log
    file(s), with the spec as keyword arguments (``columns=``, ``time=`` or
    ``sample_rate_hz=``, ... see :class:`LogSpec`), e.g.::

        import_log("run.csv", "data/run", name="my-arm", time="t",
                   columns={"q": ["q1", "q2", "q3"], "tau_m": ["tau1", "tau2", "tau3"]})

    The dataset is built beside ``out`` (under a name unique to this run) and
    renamed into place at the end, so an interrupted import leaves any previous
    dataset at ``out`` intact. An existing ``out`` is replaced only with
    ``overwrite``, and only when it is a hybrid-dyn dataset holding nothing but its
    own files (anything else is refused, named). One import per ``out`` at a time
    (``outputs.output_lock``). ``strict``: fail on any row issue and on any channel that carries nothing
    (``log_validation.channel_warnings``: a joint's torque 0 throughout). ``keep_partial``: a damaged ROS
    bag keeps the rows read before the damage, the report saying where it stopped (else a one-line error).
    """
    is_spec = isinstance(source, LogSpec) or (isinstance(source, (str, Path)) and Path(source).suffix == ".toml")
    if is_spec and spec_args:
        raise LogSpecError(f"keyword arguments {sorted(spec_args)} cannot be combined with a spec; edit the spec")
    if isinstance(source, LogSpec):
        spec = source
    elif is_spec:
        spec = read_spec(source)
    else:
        files = [source] if isinstance(source, (str, Path)) else list(source)
        spec_args.setdefault("name", re.sub(r"[^A-Za-z0-9_.-]", "_", Path(files[0]).stem))
        spec = LogSpec(files=files, **spec_args)
    out = Path(out)
    with output_lock(out, "dataset"):
        return _import_locked(spec, out, overwrite, strict, keep_partial)


def _import_locked(spec: "LogSpec", out: Path, overwrite: bool, strict: bool, keep_partial: bool) -> "ImportReport":
    check_replaceable(out, overwrite)
    spec = copy.copy(spec)  # the columns become what the log holds (a bag without velocities): not the caller's
    if spec.ros is not None and spec.trajectories == "tables":  # one trajectory per bag: streamed to the file
        from .bag_import import import_bags

        return import_bags(spec, out, overwrite, strict, keep_partial)
    segments, report = checked_segments(spec, strict, keep_partial)
    write_dataset(spec, segments, report, out, overwrite)
    return report


def checked_segments(spec: "LogSpec", strict: bool = False, keep_partial: bool = False,
                     derivatives: bool = True) -> tuple[list, "ImportReport"]:
    """The log read and checked (``log_validation.validate_log``) and refused as an import refuses it (strict,
    too many rows dropped, nothing left): its kept segments and the report. ``hybrid-dyn estimate`` replays
    these, so that it reads exactly what an import of the same spec would write (``derivatives`` False: but
    no segment is dropped for a derivative filter it does not run)."""
    report = ImportReport(spec.name)
    segments, warnings = validate_log(spec, report, keep_partial, derivatives)
    report.warnings += warnings
    refuse_as_import(spec, report, strict, len(segments))
    return segments, report


def spec_checksum(spec: LogSpec) -> str:
    """A digest of the spec and its source files: identifies an import's input."""
    h = hashlib.sha256(f"importer-{IMPORTER_VERSION}".encode())
    h.update(json.dumps(spec.to_dict(), sort_keys=True, default=str).encode())
    for f in spec.files:
        h.update(sha256_file(f).encode() if Path(f).is_file() else b"missing")
    return h.hexdigest()
