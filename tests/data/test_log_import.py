"""Real-robot log import: formats, derivative estimation, row-by-row validation, shipped logs.

References are independent of the importer: analytic derivatives of sines, the
raw .mat matrices read with scipy, and the clean log imported without defects.
"""
import json
import os
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.data import DatasetError, import_log, load_dataset
from hybrid_dyn.data.logs.real_logs import real_specs_dir
from hybrid_dyn.data.logs.importer import (
    LogSpecError, MissingColumnError, StrictImportError, TooManyRowsDroppedError, read_spec,
)

from helpers.logs import CSV_COLUMNS, FS, Q, TAU, sine_log, write_csv

SPECS = real_specs_dir()  # the specs that ship with the package (hybrid_dyn/resources/real)
SHARED = Path(os.environ.get("HYBRID_DYN_REAL_LOGS", SPECS / "logs"))


def load_all(path):
    """Every instance of every split, concatenated in time order: dict of arrays."""
    ds = load_dataset(path)
    insts = sorted((i for s in ("train", "val", "test") for i in ds.split(s)), key=lambda i: i.t[0])
    return {k: np.concatenate([np.asarray(i[k]) for i in insts]) for k in ds.fields}, ds


# ---------------------------------------------------------------------------
# Derivatives on a synthetic sine log, through the whole import


@pytest.mark.parametrize("method,tol_qdd", [("savgol", 1e-3), ("central", 1e-3), ("butter", 1e-3)])
def test_acceleration_from_logged_velocity_matches_analytic(tmp_path, method, tol_qdd):
    """Stated tolerance: with qd logged, qdd is within 0.1 % of each joint's peak acceleration
    (0.2-0.5 Hz sines at 100 Hz, every sample including both ends)."""
    log = sine_log()
    csv = write_csv(tmp_path / "sine.csv", log)
    import_log(csv, tmp_path / "ds", columns=CSV_COLUMNS, time="t", derivatives={"method": method})
    got, ds = load_all(tmp_path / "ds")
    np.testing.assert_array_equal(got["q"], log["q"])
    np.testing.assert_array_equal(got["qd"], log["qd"])
    err = np.abs(got["qdd"] - log["qdd"]).max(axis=0) / log["peak_qdd"]
    assert err.max() < tol_qdd, err
    assert ds.meta["import"]["velocities"] == "logged"
    assert ds.meta["import"]["derivatives"]["method"] == method


def test_velocity_and_acceleration_from_positions_only(tmp_path):
    """Stated tolerance (default Savitzky-Golay, 0.11 s window, cubic): without qd in the log,
    qd is within 0.1 % of its peak and qdd within 1 % of its peak at every sample."""
    log = sine_log()
    csv = write_csv(tmp_path / "sine.csv", log, with_qd=False)
    import_log(csv, tmp_path / "ds", columns={"q": Q, "tau_m": TAU}, time="t")
    got, ds = load_all(tmp_path / "ds")
    assert (np.abs(got["qd"] - log["qd"]).max(axis=0) / log["peak_qd"]).max() < 1e-3
    assert (np.abs(got["qdd"] - log["qdd"]).max(axis=0) / log["peak_qdd"]).max() < 1e-2
    assert ds.meta["import"]["velocities"] == "estimated"


def test_next_sample_column_gives_the_last_row_a_central_difference(tmp_path):
    log = sine_log(n=300)
    nxt = sine_log(n=301)  # same seed: the same sines, one sample longer
    m = np.concatenate([log["q"], log["qd"], log["tau"], nxt["q"][1:], nxt["qd"][1:]], axis=1)
    np.savez(tmp_path / "log.npz", traj=m)
    import_log(tmp_path / "log.npz", tmp_path / "ds", variables="traj", sample_rate_hz=FS,
               columns={"q": "1-7", "qd": "8-14", "tau_m": "15-21", "q_next": "22-28", "qd_next": "29-35"},
               derivatives={"method": "central"})
    got, _ = load_all(tmp_path / "ds")
    # Independent reference: the central difference written out by hand.
    qd_ext = nxt["qd"]
    expect_last = (qd_ext[300] - qd_ext[298]) / (2 / FS)
    np.testing.assert_allclose(got["qdd"][-1], expect_last, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got["qdd"][1:-1], (qd_ext[2:300] - qd_ext[:298]) * FS / 2, atol=1e-9)


# ---------------------------------------------------------------------------
# Formats: the same log as CSV, npz, .mat and Parquet gives the same dataset


def test_formats_give_identical_datasets(tmp_path):
    log = sine_log(n=200)
    write_csv(tmp_path / "log.csv", log)
    mat = np.concatenate([log["t"][:, None], log["q"], log["qd"], log["tau"]], axis=1)
    scipy.io.savemat(tmp_path / "log.mat", {"run1": mat})
    np.savez(tmp_path / "log.npz", time=log["t"], q=log["q"], qd=log["qd"], tau=log["tau"])
    imports = {
        "csv": import_log(tmp_path / "log.csv", tmp_path / "csv", columns=CSV_COLUMNS, time="t"),
        "mat": import_log(tmp_path / "log.mat", tmp_path / "mat", time=1,
                          columns={"q": "2-8", "qd": "9-15", "tau_m": "16-22"}),
        "npz": import_log(tmp_path / "log.npz", tmp_path / "npz", time="time",
                          columns={"q": "q", "qd": "qd", "tau_m": "tau"}),
    }
    pq = pytest.importorskip("pyarrow.parquet")
    import pyarrow as pa

    table = pa.table({"t": log["t"], "q": list(log["q"]), "qd": list(log["qd"]), "tau": list(log["tau"])})
    pq.write_table(table, tmp_path / "log.parquet")
    imports["parquet"] = import_log(tmp_path / "log.parquet", tmp_path / "parquet", time="t",
                                    columns={"q": "q", "qd": "qd", "tau_m": "tau"})
    ref, _ = load_all(tmp_path / "csv")
    np.testing.assert_array_equal(ref["q"], log["q"])
    np.testing.assert_array_equal(ref["tau_m"], log["tau"])
    for fmt, report in imports.items():
        got, ds = load_all(tmp_path / fmt)
        assert report.rows_kept == 200 and not report.issues, fmt
        assert sorted(ds.fields) == ["q", "qd", "qdd", "t", "tau_m"], fmt  # nothing the log lacks
        for k in ref:
            np.testing.assert_array_equal(got[k], ref[k], err_msg=f"{fmt}:{k}")


# ---------------------------------------------------------------------------
# Malformed logs: reported by row, good rows unaffected


def _compare_good_rows(bad_path, clean_path, log, dropped, breaks=()):
    """Kept rows equal the clean import's rows; qdd the same away from any break
    (beyond the filter's half window) and within the stated tolerance near one."""
    got, _ = load_all(bad_path)
    ref, _ = load_all(clean_path)
    keep = np.setdiff1d(np.arange(len(log["t"])), dropped)
    for k in ("t", "q", "qd", "tau_m"):
        np.testing.assert_array_equal(got[k], ref[k][keep], err_msg=k)
    far = np.ones(len(keep), bool)
    for b in list(breaks) + list(dropped):
        far &= np.abs(keep - b) > 6
    # Up to rounding: a segment's median time step differs from the whole log's in the last bits.
    np.testing.assert_allclose(got["qdd"][far], ref["qdd"][keep][far], rtol=1e-9, atol=1e-9)
    assert (np.abs(got["qdd"] - log["qdd"][keep]).max(axis=0) / log["peak_qdd"]).max() < 1e-2


@pytest.fixture
def clean(tmp_path):
    log = sine_log(n=600)
    write_csv(tmp_path / "clean.csv", log)
    import_log(tmp_path / "clean.csv", tmp_path / "clean", columns=CSV_COLUMNS, time="t")
    return log, tmp_path / "clean"


def test_missing_column_is_named(tmp_path, clean):
    log, _ = clean
    write_csv(tmp_path / "log.csv", log)
    text = (tmp_path / "log.csv").read_text().replace(",tau3,", ",torque3,", 1)
    (tmp_path / "log.csv").write_text(text)
    with pytest.raises(MissingColumnError, match=r"tau3.*tau_m"):
        import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t")
    assert not (tmp_path / "ds").exists()


def test_short_row_is_reported_by_row(tmp_path, clean):
    log, clean_path = clean
    row = 123
    line = ",".join(repr(float(v)) for v in [log["t"][row], *log["q"][row], *log["qd"][row]])  # no torques
    write_csv(tmp_path / "log.csv", log, rows={row: line})
    report = import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t")
    assert report.rows(kind="missing_cells") == [row + 1]
    assert report.issues[0].line == row + 2  # the header is line 1
    assert "tau_m[1]" in report.issues[0].detail and "15 cells" in report.issues[0].detail
    _compare_good_rows(tmp_path / "ds", clean_path, log, [row])


def test_nan_rows_are_reported_dropped_and_counted(tmp_path, clean):
    log, clean_path = clean
    bad = [200, 201, 450]
    write_csv(tmp_path / "log.csv", log)
    lines = (tmp_path / "log.csv").read_text().splitlines()
    for r in bad:
        cells = lines[1 + r].split(",")
        cells[3] = "nan" if r != 450 else ""  # q3: NaN, or an empty cell
        lines[1 + r] = ",".join(cells)
    (tmp_path / "log.csv").write_text("\n".join(lines) + "\n")
    report = import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t")
    assert report.rows(kind="nan") == [r + 1 for r in bad]
    assert all("q[3]" in i.detail for i in report.issues)
    assert report.rows_dropped == 3 and report.rows_kept == 597
    meta = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert meta["import"]["rows_dropped"] == 3 and meta["import"]["dropped_by_kind"] == {"nan": 3}
    assert [i["row"] for i in meta["import"]["issues_first_100"]] == [201, 202, 451]
    _compare_good_rows(tmp_path / "ds", clean_path, log, bad)
    # The gap splits the trajectory; all its segments stay in one split.
    ds = load_dataset(tmp_path / "ds")
    assert len(ds.meta["instances"]) == 3
    assert {r["trajectory"] for r in ds.meta["instances"]} == {"log"}


def test_non_monotonic_time_is_reported_by_row(tmp_path, clean):
    log, clean_path = clean
    log_bad = {k: v.copy() for k, v in log.items()}
    log_bad["t"][300] = log["t"][298]  # a stale timestamp
    log_bad["t"][301] = log["t"][301]
    write_csv(tmp_path / "log.csv", log_bad)
    report = import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t")
    assert report.rows(kind="time_order") == [301]
    assert "not after" in report.issues[0].detail
    _compare_good_rows(tmp_path / "ds", clean_path, log, [300])


def test_degrees_are_caught_by_range(tmp_path, clean):
    log, clean_path = clean
    log_bad = {k: v.copy() for k, v in log.items()}
    log_bad["q"][400] = np.degrees(log["q"][400]) + 20.0  # one row in degrees (+ offset: surely > 2 pi)
    write_csv(tmp_path / "log.csv", log_bad)
    report = import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t")
    assert report.rows(kind="unit_range") == [401]
    assert "degrees" in report.issues[0].detail
    _compare_good_rows(tmp_path / "ds", clean_path, log, [400])


def test_whole_log_in_degrees_fails_with_a_hint_and_imports_with_angle_deg(tmp_path, clean):
    log, clean_path = clean
    log_deg = dict(log, q=np.degrees(log["q"]) + 90.0, qd=np.degrees(log["qd"]))
    write_csv(tmp_path / "log.csv", log_deg)
    with pytest.raises(TooManyRowsDroppedError, match="degrees"):
        import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t")
    assert not (tmp_path / "ds").exists()
    import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t", angle_unit="deg")
    got, _ = load_all(tmp_path / "ds")
    np.testing.assert_allclose(got["q"], log["q"] + np.pi / 2, atol=1e-12)
    np.testing.assert_allclose(got["qd"], log["qd"], atol=1e-12)


def test_time_jump_is_reported_and_splits_without_dropping(tmp_path, clean):
    log, clean_path = clean
    gone = np.arange(250, 262)  # 12 samples never recorded
    keep = np.setdiff1d(np.arange(600), gone)
    write_csv(tmp_path / "log.csv", {k: (v[keep] if k in ("t", "q", "qd", "tau") else v) for k, v in log.items()})
    report = import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t")
    assert report.rows(kind="time_jump") == [251]  # the first row after the gap, 1-based in the file
    assert report.rows_dropped == 0 and report.instances == 2
    assert "13.0 x the median step" in report.issues[0].detail
    _compare_good_rows(tmp_path / "ds", clean_path, log, gone, breaks=[249, 262])


def test_missing_samples_found_by_next_sample_column(tmp_path):
    log, nxt = sine_log(n=300), sine_log(n=301)
    m = np.concatenate([log["q"], log["qd"], log["tau"], nxt["q"][1:], nxt["qd"][1:]], axis=1)
    scipy.io.savemat(tmp_path / "log.mat", {"traj1": np.delete(m, [100], axis=0), "traj2": m})
    report = import_log(tmp_path / "log.mat", tmp_path / "ds", variables="traj*", sample_rate_hz=FS,
                        columns={"q": "1-7", "qd": "8-14", "tau_m": "15-21", "q_next": "22-28", "qd_next": "29-35"})
    assert [(i.table, i.row, i.kind) for i in report.issues] == [("traj1", 101, "discontinuity")]
    assert report.rows_kept == 599 and report.trajectories == 2 and report.instances == 3


def test_strict_mode_and_existing_output_are_safe(tmp_path, clean):
    log, clean_path = clean
    before = (clean_path / "manifest.json").read_bytes()
    with pytest.raises(DatasetError, match="already exists"):
        import_log(tmp_path / "clean.csv", clean_path, columns=CSV_COLUMNS, time="t")
    log_bad = {k: v.copy() for k, v in log.items()}
    log_bad["q"][10, 0] = np.nan
    write_csv(tmp_path / "bad.csv", log_bad)
    with pytest.raises(StrictImportError, match="row 11"):
        import_log(tmp_path / "bad.csv", clean_path, columns=CSV_COLUMNS, time="t", strict=True, overwrite=True)
    assert (clean_path / "manifest.json").read_bytes() == before
    load_dataset(clean_path)


def test_a_dead_torque_channel_is_a_warning_naming_the_joint_and_strict_refuses_it(tmp_path):
    """Joint 4's torque 0 throughout once imported without a word. Now each channel that carries
    nothing is a warning naming its joint: constant (0 Nm), or far below its joint's scale (only ADC noise,
    1e-5 Nm against the other joints' 5 Nm sines: five decades, past the 1e-3 threshold); the warning reaches the
    manifest (where the bench reads it); ``strict`` refuses the log. The clean log gives none."""
    log = sine_log(n=300)
    write_csv(tmp_path / "clean.csv", log)
    clean = import_log(tmp_path / "clean.csv", tmp_path / "clean", columns=CSV_COLUMNS, time="t")
    assert not any("channel" in w for w in clean.warnings), clean.warnings
    dead = {k: v.copy() for k, v in log.items()}
    dead["tau"][:, 3] = 0.0
    dead["tau"][:, 5] = np.random.default_rng(1).normal(0, 1e-5, len(dead["t"]))
    write_csv(tmp_path / "dead.csv", dead)
    report = import_log(tmp_path / "dead.csv", tmp_path / "dead", columns=CSV_COLUMNS, time="t")
    assert report.warnings[0] == "tau_m of joint 4 is constant (0 Nm) in all 300 rows: a dead channel?"
    assert report.warnings[1].startswith("tau_m of joint 6 varies by ") and "threshold 0.001" in report.warnings[1]
    assert report.channel_warnings == report.warnings[:2]  # the two a strict import refuses
    assert load_dataset(tmp_path / "dead").meta["import"]["warnings"][:2] == report.channel_warnings
    with pytest.raises(StrictImportError, match=r"dead channels:(.|\n)*tau_m of joint 4 is constant"):
        import_log(tmp_path / "dead.csv", tmp_path / "strict", columns=CSV_COLUMNS, time="t", strict=True)
    assert not (tmp_path / "strict").exists()


def test_a_dead_channel_names_the_robots_joint_and_is_scaled_by_its_effort_limit(tmp_path):
    """With a described robot (the Panda) the warning names the joint as the URDF does, and a wrist torque
    channel (effort limit 12 Nm) moving 0.05 Nm is live: its scale is its own joint's, not the shoulder's."""
    from helpers.logs import write_log

    spec = write_log(tmp_path / "logs")
    import csv as _csv
    rows = list(_csv.reader(open(tmp_path / "logs" / "log.csv")))
    header, body = rows[0], np.array(rows[1:], float)
    rng = np.random.default_rng(2)
    body[:, header.index("tau7")] = rng.normal(0, 0.05, len(body))  # a live wrist torque
    body[:, header.index("q4")] = body[0, header.index("q4")]  # joint 4 never moves ...
    body[:, header.index("qd4")] = 0.0  # ... and says so
    np.savetxt(tmp_path / "logs" / "log.csv", body, delimiter=",", header=",".join(header), comments="", fmt="%.17g")
    report = import_log(spec, tmp_path / "ds")
    assert report.warnings == [
        f"q of joint 4 (panda_joint4) is constant ({body[0, header.index('q4')]:.6g} rad) in all 400 rows: a dead "
        "channel or a joint that never moves?",
        "qd of joint 4 (panda_joint4) is constant (0 rad/s) in all 400 rows: a dead channel?"], report.warnings


def test_wrong_sample_rate_warns(tmp_path):
    log = sine_log(n=300)
    m = np.concatenate([log["q"], log["qd"], log["tau"]], axis=1)
    np.save(tmp_path / "m.npy", m)
    np.savez(tmp_path / "log.npz", run=m)
    report = import_log(tmp_path / "log.npz", tmp_path / "ds", variables="run", sample_rate_hz=110.0,
                        columns={"q": "1-7", "qd": "8-14", "tau_m": "15-21"})
    assert any("sample rate" in w for w in report.warnings)
    report = import_log(tmp_path / "log.npz", tmp_path / "ok", variables="run", sample_rate_hz=FS,
                        columns={"q": "1-7", "qd": "8-14", "tau_m": "15-21"})
    assert not report.warnings or all("sample rate" not in w for w in report.warnings)


def test_wrong_sample_rate_warning_names_the_rate_that_fits(tmp_path):
    log = sine_log(n=300)
    np.savez(tmp_path / "log.npz", run=np.concatenate([log["q"], log["qd"], log["tau"]], axis=1))
    report = import_log(tmp_path / "log.npz", tmp_path / "ds", variables="run", sample_rate_hz=110.0,
                        columns={"q": "1-7", "qd": "8-14", "tau_m": "15-21"})
    assert any("fit a sample rate of 100 Hz, not the declared 110 Hz" in w for w in report.warnings), report.warnings


@pytest.mark.parametrize("factor, declared, fits", [(1e3, "s", "ms"), (1e6, "s", "us"), (1e9, "us", "ns")])
def test_time_in_another_unit_warns_with_the_unit_that_fits(tmp_path, factor, declared, fits):
    """t logged in ms but declared s (and the like: a declared unit too large, which imports and only
    warns): the warning names the unit whose scale makes the position increments over the time steps
    match the logged velocities; the right unit gives no warning."""
    log = sine_log(n=300)
    log_t = dict(log, t=log["t"] * factor)
    write_csv(tmp_path / "log.csv", log_t)
    report = import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t", time_unit=declared)
    assert any(f"the time column fits the unit '{fits}', not the declared '{declared}'" in w
               for w in report.warnings), report.warnings
    report = import_log(tmp_path / "log.csv", tmp_path / "ok", columns=CSV_COLUMNS, time="t", time_unit=fits)
    assert not any("position increments" in w for w in report.warnings), report.warnings


def test_utf8_bom_in_csv_header_is_not_part_of_the_first_name(tmp_path, clean):
    log, clean_path = clean
    text = (tmp_path / "clean.csv").read_bytes()
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + text)  # as Excel's "CSV UTF-8" writes it
    import_log(tmp_path / "bom.csv", tmp_path / "bom", columns=CSV_COLUMNS, time="t")
    got, _ = load_all(tmp_path / "bom")
    ref, _ = load_all(clean_path)
    for k in ref:
        np.testing.assert_array_equal(got[k], ref[k])


# ---------------------------------------------------------------------------
# Specs and CLI


def test_spec_paths_env_override_and_unknown_keys(tmp_path, monkeypatch):
    log = sine_log(n=100)
    (tmp_path / "shared").mkdir()
    write_csv(tmp_path / "shared" / "run.csv", log)
    spec = tmp_path / "specs" / "run.toml"
    spec.parent.mkdir()
    spec.write_text('name = "my-arm"\n[source]\nfiles = ["${MY_SHARED}/run.csv"]\n'
                    '[env_defaults]\nMY_SHARED = "../shared"\n[time]\ncolumn = "t"\n'
                    '[columns]\nq = "q1-q7"\ntau_m = "tau1-tau7"\n')
    with pytest.raises(MissingColumnError, match="q1-q7"):  # a range of names is not a thing: say so
        import_log(spec, tmp_path / "ds")
    spec.write_text(spec.read_text().replace('"q1-q7"', str(Q).replace("'", '"'))
                    .replace('"tau1-tau7"', str(TAU).replace("'", '"')))
    assert read_spec(spec).files == [(tmp_path / "shared" / "run.csv").resolve()]
    monkeypatch.setenv("MY_SHARED", str(tmp_path / "elsewhere"))
    assert read_spec(spec).files == [tmp_path / "elsewhere" / "run.csv"]
    monkeypatch.delenv("MY_SHARED")
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 0
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 2  # exists
    assert load_dataset(tmp_path / "ds").meta["scenario"] == "my-arm"
    spec.write_text(spec.read_text() + "[derivatives]\nmethod = \"savgol\"\nwindow = 3\n")
    with pytest.raises(LogSpecError, match="window"):
        read_spec(spec)
    spec.write_text('name = "x"\n[source]\nfiles = ["a.csv"]\nfiless = 1\n')
    with pytest.raises(LogSpecError, match="filess"):
        read_spec(spec)


# ---------------------------------------------------------------------------
# The shipped real logs (hybrid_dyn/resources/real/logs, 4.7 MB: they ship with the package)


# order: the file's column (0-based, within each 7-column group) of each of the robot's joints. Baxter's
# file holds the joints alphabetically (e0, e1, s0, s1, w0, w1, w2); its robot's chain is s0, s1, e0, ...
@pytest.mark.parametrize("name,mat,prefix,rows,order", [
    ("kuka", "KukaDirectDynamics.mat", "kukatraj", 20068, [0, 1, 2, 3, 4, 5, 6]),
    ("baxter", "BaxterDirectDynamics.mat", "baxtertraj", 19295, [2, 3, 0, 1, 4, 5, 6]),
])
def test_shipped_trajectory_logs(tmp_path, name, mat, prefix, rows, order):
    report = import_log(SPECS / f"{name}.toml", tmp_path / name)
    assert (report.rows_read, report.rows_kept, report.trajectories, report.instances) == (rows, rows, 10, 10)
    assert not report.issues and not report.warnings
    ds = load_dataset(tmp_path / name)
    assert sorted(ds.fields) == ["q", "qd", "qdd", "t", "tau_m"]
    splits = {s: [i.name for i in ds.split(s)] for s in ("train", "val", "test")}
    assert [len(v) for v in splits.values()] == [6, 2, 2]
    assert sum(len(i) for s in splits for i in ds.split(s)) == rows
    # Against the raw matrices: positions, velocities and torques verbatim.
    raw = scipy.io.loadmat(SHARED / mat)
    spec = read_spec(SPECS / f"{name}.toml")
    inst = ds.instances[f"{prefix}3"]
    m = raw[f"{prefix}3"]
    m = np.hstack([m[:, 7 * g:7 * g + 7][:, order] for g in range(5)])  # the robot's joint order
    np.testing.assert_array_equal(inst.q, m[:, :7])
    np.testing.assert_array_equal(inst.qd, m[:, 7:14])
    np.testing.assert_array_equal(inst.tau_m, m[:, 14:21])
    # qdd is the documented recipe: central difference (last row via qd(t+1)), then a
    # zero-phase 4th-order Butterworth at 5 Hz, padded by an odd extension of 2 cutoff periods.
    from scipy import signal

    dt = 1.0 / spec.sample_rate_hz
    qd_ext = np.vstack([m[:, 7:14], m[-1:, 28:35]])
    central = np.vstack([(-3 * qd_ext[0] + 4 * qd_ext[1] - qd_ext[2]) / (2 * dt),  # 2nd-order one-sided
                         (qd_ext[2:] - qd_ext[:-2]) / (2 * dt)])
    b, a = signal.butter(4, 5.0 / (0.5 / dt))
    expect = signal.filtfilt(b, a, central, axis=0, padtype="odd", padlen=int(round(2.0 / (5.0 * dt))))
    np.testing.assert_allclose(inst.qdd, expect, atol=1e-9)
    # Physics: integrating qdd gives back the logged qd, up to the noise the filter removed
    # (no drift, right scale and time base): RMS below 0.45 x the std of qd on every joint.
    integral = m[0, 7:14] + np.concatenate([np.zeros((1, 7)), np.cumsum(0.5 * (inst.qdd[1:] + inst.qdd[:-1]) * dt, axis=0)])
    assert np.all(np.sqrt(np.mean((integral - m[:, 7:14]) ** 2, axis=0)) < 0.45 * m[:, 7:14].std(axis=0))


def test_shipped_sarcos_log_in_contiguous_blocks(tmp_path):
    from hybrid_dyn.data import real_dataset

    path = real_dataset("real-sarcos", tmp_path / "cache")
    ds = load_dataset(path)
    raw = scipy.io.loadmat(SHARED / "sarcos_inv_test.mat")["sarcos_inv_test"]
    assert ds.meta["import"]["rows_read"] == ds.meta["import"]["rows_kept"] == 4449
    insts = sorted(ds.instances.values(), key=lambda i: i.t[0])
    assert len(insts) == 10 and {len(i) for i in insts} == {444, 445}
    stacked = np.concatenate([np.concatenate([i.q, i.qd, i.qdd, i.tau_m], axis=1) for i in insts])
    np.testing.assert_array_equal(stacked, raw)  # accelerations as given, rows in order, none lost
    assert [len(ds.split(s)) for s in ("train", "val", "test")] == [6, 2, 2]
    # Cached: a second call returns the same directory without importing again.
    mtime = (path / "manifest.json").stat().st_mtime_ns
    assert real_dataset("real-sarcos", tmp_path / "cache") == path
    assert (path / "manifest.json").stat().st_mtime_ns == mtime
    # A spec override is another import, cached under its own key; the rows are the file's, in order.
    chunks = real_dataset("real-sarcos", tmp_path / "cache", name="real-sarcos-chunks", n_blocks=40)
    assert chunks != path
    cds = load_dataset(chunks)
    cinsts = sorted(cds.instances.values(), key=lambda i: i.t[0])
    assert cds.meta["scenario"] == "real-sarcos-chunks" and len(cinsts) == 40 and {len(i) for i in cinsts} == {111, 112}
    np.testing.assert_array_equal(
        np.concatenate([np.concatenate([i.q, i.qd, i.qdd, i.tau_m], axis=1) for i in cinsts]), raw)


def test_import_cli_takes_a_shipped_set_by_name(tmp_path, monkeypatch):
    """``import --spec real-sarcos``: the spec inside the installed package, whose path a user need not know;
    the same dataset as the spec's path gives. A file of that name in the working folder wins over the set."""
    monkeypatch.chdir(tmp_path)
    assert cli_main(["import", "--spec", "real-sarcos", "--out", "by-name"]) == 0
    assert cli_main(["import", "--spec", str(SPECS / "sarcos.toml"), "--out", "by-path"]) == 0
    assert load_dataset(tmp_path / "by-name").checksum == load_dataset(tmp_path / "by-path").checksum
    (tmp_path / "real-sarcos").write_text("not = [a spec")  # a local file named like the set: read as the spec
    assert cli_main(["import", "--spec", "real-sarcos", "--out", "local"]) == 2
    assert not (tmp_path / "local").exists()


def test_robot_with_a_description_uses_its_joint_limits(tmp_path, panda):
    """A log from a described arm is checked against that arm's limits, not just +-2 pi."""
    log = sine_log(n=200)
    log["q"] = 0.5 * np.tanh(log["q"])  # well inside the Panda's limits
    beyond = panda.q_upper[0] + 0.3      # > limit + margin (0.2 rad), < 2 pi
    log["q"][50, 0] = beyond
    write_csv(tmp_path / "log.csv", log)
    report = import_log(tmp_path / "log.csv", tmp_path / "ds", columns=CSV_COLUMNS, time="t", robot="panda")
    assert report.rows(kind="unit_range") == [51]
    assert load_dataset(tmp_path / "ds").meta["robot"] == "panda"
    with pytest.raises(LogSpecError, match="6 joints"):
        import_log(tmp_path / "log.csv", tmp_path / "ur", columns=CSV_COLUMNS, time="t", robot="ur5")
    # Without a description the same row is within the generic +-2 pi bound.
    assert not import_log(tmp_path / "log.csv", tmp_path / "generic", columns=CSV_COLUMNS, time="t").issues
