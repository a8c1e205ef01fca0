"""The types of an import spec's fields, checked before any other check compares or uses them
(``n_blocks = nan``, ``sample_rate_hz = "abc"``, ``delimiter = 3`` once ended in tracebacks deep in the import).

Each function returns one-line problems; ``LogSpec.__post_init__`` raises them together as a LogSpecError.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import fields


def is_number(x, integer: bool = False) -> bool:
    """A finite real number (an integer when ``integer``); never a bool or a string."""
    if isinstance(x, bool) or not isinstance(x, numbers.Integral if integer else numbers.Real):
        return False
    return math.isfinite(x)


def _is_ref(x) -> bool:
    """A column reference: a 1-based number, a name or range string, or a non-empty list of those."""
    one = lambda r: isinstance(r, str) or is_number(r, integer=True)  # noqa: E731
    return one(x) or (isinstance(x, list) and bool(x) and all(one(r) for r in x))


def spec_type_problems(spec) -> list[str]:
    """Fields of a ``LogSpec`` whose type no later step can use."""
    out = []
    res = spec.encoder_resolution
    if not (res == "auto" or (isinstance(res, (int, float)) and not isinstance(res, bool) and 0 <= res < 0.01)):
        out.append(f"[encoders] resolution must be \"auto\" or a number in [0, 0.01) [rad], got {res!r}")
    if not isinstance(spec.name, str):
        out.append(f"name must be text, got {spec.name!r}")
    if not isinstance(spec.notes, str):
        out.append(f"notes must be text, got {spec.notes!r}")
    if not isinstance(spec.columns, dict):
        out.append(f"columns must be a table of signal = column reference, got {spec.columns!r}")
    else:
        out += [f"column reference of {s} must be a column number, a name, 'a-b' or a list of those, got {r!r}"
                for s, r in spec.columns.items() if not _is_ref(r)]
    for key in ("format", "variables", "delimiter"):
        value = getattr(spec, key)
        if value is not None and not isinstance(value, str):
            out.append(f"{key} must be text, got {value!r}")
    if isinstance(spec.delimiter, str) and len(spec.delimiter) != 1:
        out.append(f"delimiter must be one character, got {spec.delimiter!r}")
    for key in ("time", "trajectory_column"):
        value = getattr(spec, key)
        if value is not None and not _is_ref(value):
            out.append(f"{key} must be a column number or name, got {value!r}")
    for key in ("time_unit", "trajectories", "angle_unit"):
        if not isinstance(getattr(spec, key), str):
            out.append(f"{key} must be text, got {getattr(spec, key)!r}")
    if spec.sample_rate_hz is not None and not is_number(spec.sample_rate_hz):
        out.append(f"sample_rate_hz must be a number [Hz], got {spec.sample_rate_hz!r}")
    if not is_number(spec.n_blocks, integer=True):
        out.append(f"n_blocks must be an integer, got {spec.n_blocks!r}")
    for f in fields(spec.checks):
        value = getattr(spec.checks, f.name)
        if not is_number(value) or value < 0:
            out.append(f"[checks] {f.name} must be a non-negative number, got {value!r}")
    return out
