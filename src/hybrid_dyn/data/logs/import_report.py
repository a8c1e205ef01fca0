"""What an import found, row by row: :class:`RowIssue` and :class:`ImportReport`.

Nothing is dropped without an entry here; the report goes into the dataset's manifest
(its first issues) and beside it in full (``import_report.json``, ``import_report.txt``).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

# Issue kinds; all but the last two drop the row.
DROP_KINDS = ("missing_cells", "nan", "time_order", "unit_range", "short_segment")
SPLIT_KINDS = ("time_jump", "discontinuity")


@dataclass
class RowIssue:
    """One problem found in one row (``row`` is 1-based within its table, as in
    MATLAB; for CSV, ``line`` is the file line). ``action``: "drop" (row removed),
    "split" (a new segment starts at this row)."""

    source: str
    table: str
    row: int
    kind: str
    detail: str
    action: str
    line: int | None = None
    n_rows: int = 1

    def text(self) -> str:
        at = f"row {self.row}" + (f" (line {self.line})" if self.line is not None else "")
        return f"{Path(self.source).name}:{self.table} {at}: {self.kind}: {self.detail} -> {self.action}"


@dataclass
class ImportReport:
    """What an import read, kept, dropped and why; ``path``: the dataset written."""

    name: str
    path: Path | None = None
    rows_read: int = 0
    rows_kept: int = 0
    trajectories: int = 0
    instances: int = 0
    issues: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    # Channels that carry nothing (a joint's torque 0 throughout): also in ``warnings``; a strict import refuses them.
    channel_warnings: list = field(default_factory=list)

    @property
    def rows_dropped(self) -> int:
        return self.rows_read - self.rows_kept

    def dropped_by_kind(self) -> dict:
        out = {}
        for i in self.issues:
            if i.action == "drop":
                out[i.kind] = out.get(i.kind, 0) + i.n_rows
        return dict(sorted(out.items()))

    def issues_by_kind(self) -> dict:
        out = {}
        for i in self.issues:
            out[i.kind] = out.get(i.kind, 0) + 1
        return dict(sorted(out.items()))

    def rows(self, kind: str | None = None) -> list[int]:
        """The 1-based rows with an issue (of one kind)."""
        return [i.row for i in self.issues if kind is None or i.kind == kind]

    def summary(self) -> dict:
        return {"rows_read": self.rows_read, "rows_kept": self.rows_kept, "rows_dropped": self.rows_dropped,
                "dropped_by_kind": self.dropped_by_kind(), "issues_by_kind": self.issues_by_kind(),
                "n_issues": len(self.issues), "trajectories": self.trajectories, "instances": self.instances,
                "warnings": list(self.warnings)}

    def to_dict(self) -> dict:
        return {"name": self.name, **self.summary(), "issues": [asdict(i) for i in self.issues]}

    def text(self, max_per_kind: int = 20) -> str:
        by_kind = self.dropped_by_kind()
        lines = [f"import {self.name}: {self.rows_read} rows read, {self.rows_kept} kept, {self.rows_dropped} dropped"
                 f"{f' {by_kind}' if by_kind else ''}; {self.trajectories} trajectories, {self.instances} instances"]
        lines += [f"warning: {w}" for w in self.warnings]
        for kind, n in self.issues_by_kind().items():
            shown = [i for i in self.issues if i.kind == kind][:max_per_kind]
            lines.append(f"{kind}: {n} issues" + (f" (first {len(shown)})" if n > len(shown) else ""))
            lines += ["  " + i.text() for i in shown]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.text()
