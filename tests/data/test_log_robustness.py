"""Odd logs a user may bring: a truncated MATLAB v7.3 file, a Parquet file
with a null list cell or a text column, degrees declared on a radian log. Each ends in a dataset that
holds the good rows, or in one line naming the problem; never a traceback."""
from __future__ import annotations

import numpy as np
import pytest

from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.data import import_log, load_dataset
from hybrid_dyn.data.logs.log_readers import LogReadError

from helpers.logs import sine_log


def test_a_truncated_matlab_v73_file_is_one_line(tmp_path, capsys):
    """Finding 6: an OSError raised inside the v7.2 reader's except block (a chained traceback)."""
    import h5py

    path = tmp_path / "log.mat"
    with h5py.File(path, "w", userblock_size=512) as f:  # v7.3 = HDF5 behind a 512-byte MATLAB header
        f["run1"] = np.zeros((21, 300))
    with open(path, "r+b") as f:  # the MATLAB header scipy looks for, then cut the file short
        f.write(b"MATLAB 7.3 MAT-file".ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")
    path.write_bytes(path.read_bytes()[:2000])
    with pytest.raises(LogReadError, match="not a readable MATLAB v7.3") as err:
        import_log(path, tmp_path / "ds", time=1, columns={"q": "2-8", "tau_m": "9-15"})
    assert err.value.__cause__ is None and err.value.__suppress_context__
    assert not (tmp_path / "ds").exists()


def _parquet(tmp_path, log, **extra):
    pq = pytest.importorskip("pyarrow.parquet")
    import pyarrow as pa

    cols = {"t": log["t"], "q": list(log["q"]), "qd": list(log["qd"]), "tau": list(log["tau"]), **extra}
    pq.write_table(pa.table(cols), tmp_path / "log.parquet")
    return tmp_path / "log.parquet"


def test_parquet_null_list_cell_drops_that_row_only(tmp_path):
    """Finding 7: one null list cell failed the whole import."""
    log = sine_log(n=300)
    q = list(log["q"])
    q[120] = None
    path = _parquet(tmp_path, {**log, "q": np.asarray(log["q"])}, q=q)
    report = import_log(path, tmp_path / "ds", time="t", columns={"q": "q", "qd": "qd", "tau_m": "tau"})
    assert report.rows_read == 300 and report.rows_kept == 299
    assert report.rows(kind="missing_cells") + report.rows(kind="nan") == [121]  # 1-based
    ds = load_dataset(tmp_path / "ds")
    t = np.sort(np.concatenate([i.t for s in ("train", "val", "test") for i in ds.split(s)]))
    np.testing.assert_array_equal(t, np.delete(log["t"], 120))


def test_parquet_unmapped_text_column_is_ignored_and_a_mapped_one_named(tmp_path):
    """Finding 7: an unmapped string column failed the whole import."""
    log = sine_log(n=300)
    path = _parquet(tmp_path, log, note=["ok"] * 300)
    report = import_log(path, tmp_path / "ds", time="t", columns={"q": "q", "qd": "qd", "tau_m": "tau"})
    assert report.rows_kept == 300 and not report.issues
    # Mapped, the text column's cells are named by row (here the time column: every row has no time).
    from hybrid_dyn.data.logs.importer import TooManyRowsDroppedError

    with pytest.raises(TooManyRowsDroppedError, match="no value in t") as err:
        import_log(path, tmp_path / "ds2", time="note", columns={"q": "q", "qd": "qd", "tau_m": "tau"})
    assert "column 'note': 'ok' is not a number" in str(err.value)
    assert not (tmp_path / "ds2").exists()


def test_degrees_declared_on_a_radian_panda_log_are_refused(tmp_path, capsys):
    """Finding 7: angle = "deg" on a radian log imported (q4 = -0.04 rad lies outside the Panda's
    [-3.07, -0.07], but import checked only a symmetric bound), and the bench printed hundreds of
    JointLimitWarning lines."""
    from helpers.logs import write_log

    spec = write_log(tmp_path / "logs", n=200)
    spec.write_text(spec.read_text() + '[units]\nangle = "deg"\n')
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 2
    err = capsys.readouterr().err
    assert 'angle = "deg", but every logged joint position lies within +-pi' in err
    assert not (tmp_path / "ds").exists()
    # The same log declared in radians imports.
    spec.write_text(spec.read_text().replace('angle = "deg"', 'angle = "rad"'))
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 0


def test_the_panda_joint_bound_is_asymmetric(tmp_path):
    """Joint 4 of the Panda lies in [-3.07, -0.07] rad: +1.0 rad is out of range (the symmetric bound
    +-3.27 let it through), -1.0 is not."""
    from helpers.logs import HOME, write_log

    spec = write_log(tmp_path / "logs", n=400)
    text = (tmp_path / "logs" / "log.csv").read_text().splitlines()
    cells = text[141].split(",")  # row 141, mid-block: both sides keep the filter's 11 rows
    assert float(cells[4]) == pytest.approx(HOME[3] + 0.3 * np.sin(1.75 * 1.4), abs=1e-9)  # its q4
    cells[4] = "1.0"
    text[141] = ",".join(cells)
    (tmp_path / "logs" / "log.csv").write_text("\n".join(text) + "\n")
    report = import_log(spec, tmp_path / "ds")
    assert report.rows(kind="unit_range") == [141]
    assert "q[4] = 1 rad is outside [-3.27, 0.13] rad" in report.text()
