"""Reading robot logs (CSV, npz, MATLAB .mat, Parquet) into plain numeric tables.

Every reader returns :class:`LogTable` objects: a float64 matrix (rows = samples)
with one name per column. Nothing here interprets the columns; that is the
importer's job. Nothing executes code on load: npz is read with
``allow_pickle=False``, .mat with ``scipy.io.loadmat`` (v4-v7.2) or h5py
(v7.3), CSV with the standard library, Parquet with pyarrow (optional extra
``hybrid-dyn[parquet]``).

Column names:
- a 2-D matrix (a .mat or npz variable) has columns "1" .. "C" (1-based, as in
  MATLAB and most data sheets);
- named 1-D arrays (npz keys, CSV header cells, Parquet columns) keep their names;
- a named 2-D array ``q`` of width k (npz) or a list column (Parquet) becomes
  "q[1]" .. "q[k]", and the name "q" refers to all of them.

Cells that cannot be read (empty CSV cells, "nan", text in a numeric column,
short CSV rows) become NaN and are listed in ``LogTable.cell_problems`` by row,
so the importer reports them instead of silently losing them.
"""
from __future__ import annotations

import csv
import fnmatch
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..dataset import DatasetError

FORMATS = ("csv", "npz", "mat", "parquet")


class LogReadError(DatasetError):
    """A log file cannot be read (missing, wrong format, no numeric data)."""


@dataclass
class LogTable:
    """One table of a log: ``data`` (T, C) float64 and ``columns`` (C names).

    ``name``: the trajectory's name (variable name, or file stem);
    ``source``: the file; ``cell_problems``: (row, message) for cells read as NaN
    (row is 0-based into ``data``); ``first_line``: the file line of row 0 (CSV).
    """

    name: str
    source: Path
    data: np.ndarray
    columns: list[str]
    cell_problems: list[tuple[int, str]] = field(default_factory=list)
    first_line: int | None = None

    def __len__(self) -> int:
        return len(self.data)


def detect_format(path: Path, fmt: str | None = None) -> str:
    if fmt:
        if fmt not in FORMATS:
            raise LogReadError(f"log format must be one of {FORMATS}, got {fmt!r}")
        return fmt
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix in ("csv", "txt", "tsv"):
        return "csv"
    if suffix in ("pq", "parquet"):
        return "parquet"
    if suffix in FORMATS:
        return suffix
    raise LogReadError(f"{path}: cannot tell the log format from the suffix {suffix!r}; give format = one of {FORMATS}")


def read_log(path, fmt: str | None = None, variables: str | None = None, delimiter: str | None = None) -> list[LogTable]:
    """Read one log file into tables.

    ``variables``: for .mat and npz, a glob pattern (e.g. ``"kukatraj*"``): each
    matching 2-D variable is one table (one trajectory), in natural order
    (traj2 before traj10). Without it, a .mat file must hold one 2-D variable and
    an npz file is read as one table of equal-length named arrays.
    """
    path = Path(path)
    if not path.is_file():
        raise LogReadError(f"log file {path} does not exist")
    fmt = detect_format(path, fmt)
    if fmt == "csv":
        return [_read_csv(path, delimiter)]
    if fmt == "parquet":
        return [_read_parquet(path)]
    arrays = _read_mat(path) if fmt == "mat" else _read_npz(path)
    if variables is not None:
        names = sorted((k for k in arrays if fnmatch.fnmatchcase(k, variables)), key=natural_key)
        if not names:
            raise LogReadError(f"{path}: no variable matches {variables!r}; variables: {sorted(arrays)}")
        tables = []
        for k in names:
            a = np.asarray(arrays[k])
            if a.ndim != 2 or not np.issubdtype(a.dtype, np.number):
                raise LogReadError(f"{path}: variable {k!r} is not a 2-D numeric matrix (shape {a.shape}, {a.dtype})")
            tables.append(LogTable(k, path, a.astype(np.float64), [str(i + 1) for i in range(a.shape[1])]))
        return tables
    if fmt == "mat":
        mats = [k for k, a in arrays.items() if np.asarray(a).ndim == 2 and np.issubdtype(np.asarray(a).dtype, np.number)]
        if len(mats) != 1:
            raise LogReadError(f"{path}: holds {len(mats)} numeric matrices {sorted(mats)}; name the ones to read "
                               f"with variables = \"<glob>\"")
        a = np.asarray(arrays[mats[0]], dtype=np.float64)
        return [LogTable(mats[0], path, a, [str(i + 1) for i in range(a.shape[1])])]
    return [_named_table(path.stem, path, arrays)]


def natural_key(name: str):
    """Sort key that puts traj2 before traj10."""
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", name)]


def _read_mat(path: Path) -> dict:
    import scipy.io

    try:
        return {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
    except NotImplementedError:  # MATLAB v7.3 files are HDF5: read below, outside this handler
        pass
    except (ValueError, TypeError, OSError) as err:
        raise LogReadError(f"{path}: not a readable MATLAB file: {err}") from err
    import h5py

    try:
        with h5py.File(path, "r") as f:
            # MATLAB stores column-major: transpose back to rows = samples.
            return {k: np.asarray(f[k][()]).T for k in f if isinstance(f[k], h5py.Dataset)}
    except (OSError, KeyError, ValueError, TypeError) as err:  # a truncated v7.3 file was once a traceback
        raise LogReadError(f"{path}: not a readable MATLAB v7.3 (HDF5) file: {err}") from None


def _read_npz(path: Path) -> dict:
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (ValueError, OSError) as err:
        raise LogReadError(f"{path}: not a readable npz file (object arrays are refused): {err}") from err


def _named_table(name: str, path: Path, arrays: dict) -> LogTable:
    """Equal-length named arrays side by side; 2-D ones become key[1..k]."""
    cols, names = [], []
    lengths = {k: len(np.atleast_1d(a)) for k, a in arrays.items()}
    if len(set(lengths.values())) > 1:
        raise LogReadError(f"{path}: arrays have different lengths {lengths}; give variables = \"<glob>\" "
                           f"to read 2-D matrices one trajectory each")
    for k in sorted(arrays):
        a = np.asarray(arrays[k])
        if not np.issubdtype(a.dtype, np.number):
            raise LogReadError(f"{path}: array {k!r} is not numeric ({a.dtype})")
        if a.ndim == 1:
            cols.append(a[:, None].astype(np.float64))
            names.append(k)
        elif a.ndim == 2:
            cols.append(a.astype(np.float64))
            names += [f"{k}[{i + 1}]" for i in range(a.shape[1])]
        else:
            raise LogReadError(f"{path}: array {k!r} has {a.ndim} dimensions; logs are 1-D or 2-D")
    if not cols:
        raise LogReadError(f"{path}: no arrays")
    return LogTable(name, path, np.concatenate(cols, axis=1), names)


def _read_csv(path: Path, delimiter: str | None) -> LogTable:
    # utf-8-sig drops a byte-order mark (Excel writes one), which would else be part of the first name.
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise LogReadError(f"{path}: not a UTF-8 text file ({err.reason} at byte {err.start})") from err
    lines = text.splitlines()
    if not lines:
        raise LogReadError(f"{path}: empty file")
    if delimiter is None:
        try:
            delimiter = csv.Sniffer().sniff(lines[0], delimiters=",;\t ").delimiter
        except csv.Error:
            delimiter = ","
    rows = list(csv.reader(lines, delimiter=delimiter, skipinitialspace=True))
    header = rows[0]
    has_header = any(not _is_number(c) for c in header if c.strip())
    if has_header:
        names = [c.strip() for c in header]
        body, first_line = rows[1:], 2
    else:
        names = [str(i + 1) for i in range(len(header))]
        body, first_line = rows, 1
    width = len(names)
    data = np.full((len(body), width), np.nan)
    problems = []
    for r, row in enumerate(body):
        if len(row) != width:
            problems.append((r, f"has {len(row)} cells, the header has {width}"))
        for c, cell in enumerate(row[:width]):
            try:
                data[r, c] = float(cell) if cell.strip() else np.nan
            except ValueError:
                problems.append((r, f"column {names[c]!r}: {cell!r} is not a number"))
    return LogTable(path.stem, path, data, names, problems, first_line)


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _read_parquet(path: Path) -> LogTable:
    try:
        import pyarrow.parquet as pq
    except ImportError as err:
        raise LogReadError("reading Parquet needs pyarrow: pip install 'hybrid-dyn[parquet]'") from err
    try:
        table = pq.read_table(path)
    except Exception as err:  # pyarrow raises its own error types
        raise LogReadError(f"{path}: not a readable Parquet file: {err}") from err
    arrays, problems = {}, []
    for name in table.column_names:
        col = table.column(name).to_numpy(zero_copy_only=False)
        if col.dtype == object or not np.issubdtype(col.dtype, np.number):
            col = _parquet_cells(name, col, problems)
        arrays[name] = col
    out = _named_table(path.stem, path, arrays)
    out.cell_problems = problems
    return out


def _parquet_cells(name: str, col: np.ndarray, problems: list) -> np.ndarray:
    """A list column (one row = one vector) or a column of text, as float64; a cell that is null, not a
    number or of another length is NaN and listed by row, so that only a row whose *mapped* cells are bad
    is dropped (a null list cell or an unmapped text column failed the whole import once)."""
    def vector(v):
        try:
            a = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            return None
        return a if a.ndim <= 1 else None

    cells = [None if v is None else vector(v) for v in col]
    widths = [a.size for a in cells if a is not None and a.ndim == 1]
    width = max(set(widths), key=widths.count) if widths else None
    out = np.full((len(col), width) if width is not None else len(col), np.nan)
    for r, a in enumerate(cells):
        ok = a is not None and (a.ndim == 1 and a.size == width if width is not None else a.ndim == 0)
        if ok:
            out[r] = a
        else:
            problems.append((r, f"column {name!r}: {col[r]!r} is not a number" if width is None else
                             f"column {name!r}: {'null' if col[r] is None else 'not a list of ' + str(width) + ' numbers'}"))
    return out
