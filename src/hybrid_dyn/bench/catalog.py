"""Every bench row, declared: importing this module completes ``rows.ROWS``.

The three declaring modules are imported in the order results.csv lists rows:
analytic, learned (tip force, then joint torque), identified. A row declared
elsewhere (a test's toy row, a user's own) is appended after them.
"""
from __future__ import annotations

from . import analytic_rows, learned_rows, identified_rows  # noqa: F401  (they declare the rows)
from .families import FAMILIES
from .rows import ROWS, Row

__all__ = ["ROWS", "reference_label", "select_rows"]


def select_rows(names=(), families=()) -> list[Row]:
    """The declared rows named in ``names`` or of a family in ``families``, in declaration order
    (an unknown name or family is refused, naming it)."""
    from ..errors import UsageError

    unknown = ROWS.missing(names)
    if unknown:
        raise UsageError(f"unknown bench rows {unknown}; known: {', '.join(ROWS)}")
    bad = FAMILIES.missing(families)
    if bad:
        raise UsageError(f"unknown bench families {bad}; known: {', '.join(FAMILIES)}")
    return [r for r in ROWS.values() if r.name in names or r.family in families]


def reference_label(model: str) -> str | None:
    """The label of a reference row (e.g. ``seed-tip-11-raw``), None for any other row or a name not declared."""
    row = ROWS.get(str(model))
    return row.reference if row is not None else None
