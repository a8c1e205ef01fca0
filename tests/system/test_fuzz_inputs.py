"""Fuzz of the import spec and the URDF reader: seeded random structural mutations of a
valid spec (and of its log file) and of a valid URDF. Every case must end, within its time limit, in a
HybridDynError that names the problem, or in a dataset that loads (a robot that computes); never in
another exception (a traceback) or a hang, and a refused import leaves no output behind.

The bench's folders too: ``report`` and ``compare`` (with ``--out``) on report folders changed at
random, and ``study --out`` on folders holding a mix of the study's files and a user's. They must end in
a report, comparison or summary showing only what the bench wrote, or in one error; and no file of the
user's, in the folder or at ``--out``, is ever written over or deleted.

The seeds are fixed: a failure here is reproducible by its case number, printed in the assertion.
"""
from __future__ import annotations

import copy
import shutil
import traceback
from pathlib import Path

import numpy as np
import pytest

from hybrid_dyn.errors import HybridDynError

from helpers.timelimit import TimeLimitExceeded, time_limit

pytestmark = pytest.mark.system

N_SPEC_CASES = 300
N_URDF_CASES = 300
SPEC_SEED, URDF_SEED = 28, 2028
CASE_LIMIT_S = 10.0  # one case: an import of a 60-row log or one URDF load takes well under a second
# Errors whose message is a headline and then the import's row report (by design: the rows are named).
REPORT_ERRORS = ("TooManyRowsDroppedError", "StrictImportError", "LogImportError")

# Values a mutation may put anywhere: wrong types, out of range, odd text.
ODD = [None, True, 0, -1, 1, 2, 10**9, -0.5, 0.0, 0.99, 1.0, float("nan"), float("inf"), "", "abc", "0.2", "1-99",
       "q", "t", [], [1, "x"], ["q1", "q1"], {}, {"a": 1}, "${NOPE}", "../../etc", "ms", "deg", "blocks", "column"]


def _log(folder: Path, n: int = 60) -> None:
    """A small 3-joint log with a time column, positions, velocities, torques and a trajectory id."""
    t = np.arange(n) / 100.0
    q = 0.3 * np.sin(np.outer(t, [1.0, 1.5, 2.0]))
    qd = 0.3 * np.cos(np.outer(t, [1.0, 1.5, 2.0])) * [1.0, 1.5, 2.0]
    tau = np.cos(np.outer(t, [1.0, 2.0, 3.0]))
    traj = (np.arange(n) // 20).astype(float)
    header = "t," + ",".join(f"{k}{j}" for k in ("q", "qd", "tau") for j in (1, 2, 3)) + ",traj"
    np.savetxt(folder / "log.csv", np.column_stack([t, q, qd, tau, traj]), delimiter=",", header=header,
               comments="", fmt="%.12g")


BASE_SPEC = {
    "name": "fuzz", "robot": "unknown",
    "source": {"files": ["log.csv"]},
    "time": {"column": "t", "unit": "s"},
    "columns": {"q": ["q1", "q2", "q3"], "qd": ["qd1", "qd2", "qd3"], "tau_m": "8-10"},
    "trajectories": {"from": "blocks", "n_blocks": 3},
    "units": {"angle": "rad"},
    "split": {"seed": 0, "test_frac": 0.34, "val_frac": 0.5},
}


def _mutate_spec(doc: dict, rng) -> str:
    """One random structural change of ``doc`` in place; returns what it did."""
    sections = [k for k, v in doc.items() if isinstance(v, dict)]
    kind = rng.integers(6)
    if kind == 0:  # delete a key
        sec = rng.choice(sections + [""])
        table = doc if sec == "" else doc[sec]
        if table:
            key = rng.choice(sorted(table))
            del table[key]
            return f"del {sec}.{key}"
    if kind == 1:  # a key to an odd value
        sec = rng.choice(sections + [""])
        table = doc if sec == "" else doc[sec]
        if table:
            key = rng.choice(sorted(table))
            table[key] = copy.deepcopy(ODD[rng.integers(len(ODD))])
            return f"{sec}.{key} = {table[key]!r}"
    if kind == 2:  # an unknown or misplaced key
        sec = rng.choice(sections)
        key = rng.choice(["n_blocks", "column", "seed", "foo", "files", "unit", "angle"])
        doc[sec][key] = copy.deepcopy(ODD[rng.integers(len(ODD))])
        return f"{sec}.{key} = {doc[sec][key]!r}"
    if kind == 3:  # a section to a non-table
        sec = rng.choice(sections)
        doc[sec] = copy.deepcopy(ODD[rng.integers(len(ODD))])
        return f"[{sec}] = {doc[sec]!r}"
    if kind == 4:  # a column reference
        sig = rng.choice(["q", "qd", "qdd", "tau_m", "tau_J", "base_wrench", "tip_force", "q_next", "bogus"])
        refs = [["q1", "q2"], "1-3", "2-4", 99, "tau", ["tau1", "tau2", "tau3"], "traj", "0-2", [1, 2, 3]]
        ref = refs[rng.integers(len(refs))] if rng.random() < 0.8 else ODD[rng.integers(len(ODD))]
        cols = doc.setdefault("columns", {})
        if isinstance(cols, dict):
            cols[str(sig)] = copy.deepcopy(ref)
            return f"columns.{sig} = {ref!r}"
    doc.setdefault("trajectories", {})
    if isinstance(doc["trajectories"], dict):  # kind 5: the trajectory mode
        doc["trajectories"].update({"from": rng.choice(["tables", "blocks", "column"]),
                                    "n_blocks": int(rng.integers(-1, 8)), "column": rng.choice(["traj", "t", 42])})
        return f"trajectories = {doc['trajectories']!r}"
    return "none"


def _mutate_log(path: Path, rng) -> str:
    """One random change of the log file's bytes or rows."""
    text = path.read_text()
    lines = text.splitlines()
    kind = rng.integers(6)
    if kind == 0:
        path.write_text(text[: int(rng.integers(len(text)))])
        return "truncated"
    if kind == 1:
        i = int(rng.integers(1, len(lines)))
        lines[i] = rng.choice(["", "a,b,c", "1,2", ",,,,,,,,,,,", "nan," * 11 + "nan", "1e400," * 11 + "1"])
    elif kind == 2:
        path.write_bytes(bytes(rng.integers(0, 256, 300, dtype=np.uint8)))
        return "random bytes"
    elif kind == 3:
        lines = lines[:1]
    elif kind == 4:
        lines[0] = lines[0].replace("q1", "q1,extra")
    else:
        i = int(rng.integers(2, len(lines)))
        lines[i], lines[i - 1] = lines[i - 1], lines[i]  # time out of order
    path.write_text("\n".join(lines) + "\n")
    return f"log change {kind}"


def _check_outcome(run, what: str, allow_report: bool = False):
    """Run ``run()`` under the time limit: a HybridDynError (one line unless a row report follows) or a
    result; anything else fails with the case's description and the traceback."""
    try:
        with time_limit(CASE_LIMIT_S, what):
            return "ok", run()
    except HybridDynError as err:
        text = str(err)
        assert text.strip(), f"{what}: an empty error message ({type(err).__name__})"
        if not (allow_report and type(err).__name__ in REPORT_ERRORS):
            assert "\n" not in text.strip(), f"{what}: a multi-line {type(err).__name__}: {text[:500]}"
        return "refused", err
    except TimeLimitExceeded:
        pytest.fail(f"{what}: no answer within {CASE_LIMIT_S} s (a hang)")
    except Exception:  # noqa: BLE001 - the point: no other exception may escape
        pytest.fail(f"{what}: a traceback instead of a HybridDynError:\n{traceback.format_exc(limit=6)}")


@pytest.mark.slow  # a few hundred imports, ~10-20 s on 2 busy cores
def test_fuzzed_import_specs_end_in_a_dataset_or_one_error(tmp_path):
    from hybrid_dyn.data import import_log, load_dataset
    from hybrid_dyn.data.logs.importer import spec_from_dict

    rng = np.random.default_rng(SPEC_SEED)
    counts = {"ok": 0, "refused": 0}
    for case in range(N_SPEC_CASES):
        here = tmp_path / f"c{case:03d}"
        here.mkdir()
        _log(here)
        doc = copy.deepcopy(BASE_SPEC)
        did = [_mutate_spec(doc, rng) for _ in range(1 if rng.random() < 0.7 else 2)]
        if rng.random() < 0.15:
            did.append(_mutate_log(here / "log.csv", rng))
        what = f"spec case {case} ({'; '.join(did)})"
        out = here / "ds"

        def run():
            spec = spec_from_dict(doc, base_dir=here)
            report = import_log(spec, out)
            ds = load_dataset(out)  # a dataset that loads, every instance readable and finite
            for name in ds.meta["splits"]["train"] + ds.meta["splits"]["val"] + ds.meta["splits"]["test"]:
                assert np.isfinite(ds.instances[name]["q"]).all(), f"{what}: {name} holds non-finite q"
            return report

        status, _ = _check_outcome(run, what, allow_report=True)
        counts[status] += 1
        if status == "refused":  # nothing of the refused import is left: no dataset, no partial build
            left = sorted(p.name for p in here.iterdir() if not p.name.endswith(".lock"))
            assert left == ["log.csv"], f"{what}: refused, but left {left}"
        shutil.rmtree(here)
    # The fuzz exercised both outcomes (a mutation set that only ever fails tests nothing of the loader).
    assert counts["ok"] >= N_SPEC_CASES // 20 and counts["refused"] >= N_SPEC_CASES // 4, counts
    print(f"import spec fuzz: {counts}")


BASE_URDF = """<robot name="arm">
  <link name="base"><inertial><mass value="2"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="l1"><inertial><origin xyz="0 0 0.1"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.1 0 0"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="tool0"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="50" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.2" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="50" velocity="2"/></joint>
  <joint name="j3" type="fixed"><parent link="l2"/><child link="tool0"/><origin xyz="0.2 0 0" rpy="0 0 0"/></joint>
</robot>"""


def _mutate_urdf(root, rng) -> str:
    """One random structural change of a URDF element tree in place."""
    links, joints = root.findall("link"), root.findall("joint")
    names = [ln.get("name") for ln in links]
    kind = rng.integers(8)
    if kind == 0 and joints:  # remove a joint's parent or child, or a joint
        j = joints[rng.integers(len(joints))]
        tag = rng.choice(["parent", "child", "axis", "limit", "origin", None])
        if tag is None:
            root.remove(j)
            return f"removed joint {j.get('name')}"
        for el in j.findall(str(tag)):
            j.remove(el)
        return f"removed {tag} of {j.get('name')}"
    if kind == 1 and links:  # remove a link
        ln = links[rng.integers(len(links))]
        root.remove(ln)
        return f"removed link {ln.get('name')}"
    if kind == 2 and joints:  # point a joint end at another or unknown link (cycles, two parents)
        j = joints[rng.integers(len(joints))]
        tag = rng.choice(["parent", "child"])
        el = j.find(str(tag))
        if el is not None:
            el.set("link", str(rng.choice(names + ["nowhere"])))
            return f"{j.get('name')}.{tag} -> {el.get('link')}"
    if kind == 3:  # a joint that closes a cycle
        import xml.etree.ElementTree as ET

        a, b = rng.choice(names, 2)
        j = ET.SubElement(root, "joint", name=f"x{rng.integers(100)}", type=str(rng.choice(["fixed", "revolute"])))
        ET.SubElement(j, "parent", link=str(a))
        ET.SubElement(j, "child", link=str(b))
        return f"added joint {a} -> {b}"
    if kind == 4:  # an attribute to garbage
        els = [e for e in root.iter() if e.attrib]
        e = els[rng.integers(len(els))]
        key = rng.choice(sorted(e.attrib))
        e.set(str(key), str(rng.choice(["", "abc", "nan", "1 2", "inf", "-1", "0 0 0 0", "1e999"])))
        return f"{e.tag}.{key} = {e.get(str(key))!r}"
    if kind == 5:  # duplicate a link or joint
        import copy as _copy

        el = (links + joints)[rng.integers(len(links) + len(joints))]
        root.append(_copy.deepcopy(el))
        return f"duplicated {el.tag} {el.get('name')}"
    if kind == 6:  # a joint type
        if joints:
            j = joints[rng.integers(len(joints))]
            j.set("type", str(rng.choice(["fixed", "continuous", "prismatic", "floating", "planar", "bogus", ""])))
            return f"{j.get('name')}.type = {j.get('type')!r}"
    # kind 7: remove a name
    els = links + joints
    if els:
        e = els[rng.integers(len(els))]
        e.attrib.pop("name", None)
        return f"unnamed a {e.tag}"
    return "none"


@pytest.mark.slow  # a few hundred URDF loads, ~10 s on 2 busy cores
def test_fuzzed_urdfs_end_in_a_robot_or_one_error(tmp_path):
    import xml.etree.ElementTree as ET

    from hybrid_dyn.analytic.robot import load_robot

    rng = np.random.default_rng(URDF_SEED)
    counts = {"ok": 0, "refused": 0}
    for case in range(N_URDF_CASES):
        root = ET.fromstring(BASE_URDF)
        did = [_mutate_urdf(root, rng) for _ in range(1 if rng.random() < 0.7 else 2)]
        text = ET.tostring(root, encoding="unicode")
        if rng.random() < 0.1:
            text = text[: int(rng.integers(len(text)))]
            did.append("truncated")
        path = tmp_path / f"c{case:03d}.urdf"
        path.write_text(text)
        what = f"URDF case {case} ({'; '.join(did)})"

        def run():
            robot = load_robot(str(path))
            q = np.zeros(robot.nv)
            tau = robot.inverse_dynamics(q, q, q)
            assert tau.shape == (robot.nv,) and np.isfinite(tau).all(), f"{what}: torques {tau}"
            return robot

        status, _ = _check_outcome(run, what)
        counts[status] += 1
    assert counts["ok"] >= N_URDF_CASES // 20 and counts["refused"] >= N_URDF_CASES // 4, counts
    print(f"URDF fuzz: {counts}")


SPEC_TOML = """name = "fuzz"
robot = "unknown"
[source]
files = ["log.csv"]
[time]
column = "t"
unit = "s"
[columns]
q = ["q1", "q2", "q3"]
qd = ["qd1", "qd2", "qd3"]
tau_m = "8-10"
[trajectories]
from = "blocks"
n_blocks = 3
[split]
seed = 0
test_frac = 0.34
val_frac = 0.5
"""


@pytest.mark.slow  # 150 imports from mutated TOML text, a few seconds
def test_fuzzed_spec_files_end_in_a_dataset_or_one_error(tmp_path):
    """The spec file's text itself: lines dropped, repeated or swapped, characters inserted; read by
    ``hybrid-dyn import --spec`` as a user's file would be (TOML errors included)."""
    from hybrid_dyn.data import import_log, load_dataset
    from hybrid_dyn.data.logs.importer import read_spec

    rng = np.random.default_rng(SPEC_SEED + 1)
    counts = {"ok": 0, "refused": 0}
    for case in range(150):
        here = tmp_path / f"t{case:03d}"
        here.mkdir()
        _log(here)
        lines = SPEC_TOML.splitlines()
        did = []
        for _ in range(1 if rng.random() < 0.7 else 2):
            i = int(rng.integers(len(lines)))
            kind = int(rng.integers(4))
            if kind == 0:
                did.append(f"dropped {lines.pop(i)!r}")
            elif kind == 1:
                lines.insert(i, lines[i])
                did.append(f"repeated {lines[i]!r}")
            elif kind == 2:
                j = int(rng.integers(len(lines)))
                lines[i], lines[j] = lines[j], lines[i]
                did.append(f"swapped lines {i} and {j}")
            else:
                k = int(rng.integers(len(lines[i]) + 1))
                lines[i] = lines[i][:k] + str(rng.choice(list("=[]\"'#,.-1a \\"))) + lines[i][k:]
                did.append(f"line {i} -> {lines[i]!r}")
        (here / "spec.toml").write_text("\n".join(lines) + "\n")
        what = f"TOML case {case} ({'; '.join(did)})"

        def run():
            report = import_log(read_spec(here / "spec.toml"), here / "ds")  # what hybrid-dyn import --spec runs
            load_dataset(here / "ds")
            return report

        status, _ = _check_outcome(run, what, allow_report=True)
        counts[status] += 1
        if status == "refused":
            left = sorted(p.name for p in here.iterdir() if not p.name.endswith(".lock"))
            assert left == ["log.csv", "spec.toml"], f"{what}: refused, but left {left}"
        shutil.rmtree(here)
    assert counts["ok"] >= 10 and counts["refused"] >= 30, counts
    print(f"spec file fuzz: {counts}")


@pytest.mark.slow  # 200 report redraws without figures, a few seconds
def test_fuzzed_run_json_ends_in_a_report_or_one_error(tmp_path, monkeypatch):
    """``hybrid-dyn report`` on a run.json edited at random (keys dropped, odd values at every level): a
    README or one HybridDynError, never a traceback. The figures are stubbed out (they read results.csv
    and predictions.h5, not run.json), so each case takes milliseconds."""
    import json

    from hybrid_dyn.bench import report as report_mod
    from hybrid_dyn.bench.integrity import run_digest, results_digest
    from hybrid_dyn.bench.results import write_results

    monkeypatch.setattr(report_mod, "_figures", lambda *a, **k: [])
    monkeypatch.setattr(report_mod, "learning_curve_figures", lambda *a, **k: [])
    row = {"task": "joint_torque", "scenario": "s", "model": "rnea", "family": "analytic", "inputs": "q, qd, qdd",
           "status": "ok", "val_loss": 0.1, "test_loss": 0.1, "rmse": 1.0, "nmse": 0.1}
    base = {"bench_report": 1, "wall_seconds": 60.0, "scenarios": {"s": "data/s"}, "skipped": [
        {"scenario": "s", "task": "tip_force", "model": "x", "reason": "needs tip_force"}],
            "invocations": [{"wall_seconds": 60.0, "rows": 1}],
            "machine": {"machine": "x86_64", "processor": "cpu", "python": "3.11", "packages": {"numpy": "2"}},
            "datasets": {"s": {"path": "data/s", "checksum": "abc", "seed": 0, "config_hash": None, "robot": "panda"}},
            "profile": {"name": "data", "scenarios": ["data/s"], "generator_profile": "quick", "seed": 0,
                        "recipe": "default", "train": {}, "notes": ["a note"], "robot": None}}
    rng = np.random.default_rng(SPEC_SEED + 2)
    counts = {"ok": 0, "refused": 0}
    for case in range(200):
        here = tmp_path / f"r{case:03d}"
        here.mkdir()
        write_results(here / "results.csv", [row])
        meta = copy.deepcopy(base)
        meta["results_digest"] = results_digest(here / "results.csv", meta)
        did = []
        for _ in range(1 if rng.random() < 0.6 else 2):
            holders = [meta] + [v for v in meta.values() if isinstance(v, dict)] + \
                [v for v in meta.values() if isinstance(v, list) and v and isinstance(v[0], dict)]
            holder = holders[rng.integers(len(holders))]
            if isinstance(holder, list):
                holder = holder[0]
            if not holder:
                continue
            key = sorted(holder)[rng.integers(len(holder))]
            if rng.random() < 0.3:
                del holder[key]
                did.append(f"del {key}")
            else:
                holder[key] = copy.deepcopy(ODD[rng.integers(len(ODD))])
                did.append(f"{key} = {holder[key]!r}")
        if isinstance(meta.get("results_digest"), dict):  # re-digested, as a careful editor would: the point
            meta["results_digest"]["run"] = run_digest(meta)  # here is write_report's robustness to odd fields
        (here / "run.json").write_text(json.dumps(meta, allow_nan=True))
        what = f"run.json case {case} ({'; '.join(did)})"
        status, _ = _check_outcome(lambda: report_mod.rebuild_report(here, log=lambda m: None), what)
        counts[status] += 1
        shutil.rmtree(here)
    assert counts["ok"] >= 20 and counts["refused"] >= 20, counts
    print(f"run.json fuzz: {counts}")


# ------------------------------------------------------------------ report folders
# A user's files in and beside the report folders: whatever a command does, they stay as they are.
USER_FILES = {"notes.txt": b"my notes", "traces_my_experiment.png": b"\x89PNG mine", "rmse_by_family_mine_v2.png": b"mine"}
MLP_RMSE = "1.568"  # seed-tau-mlp's RMSE as the bench wrote it: the only figure compare may print for it
REPORT_ROWS = [{"task": "joint_torque", "scenario": "s", "model": m, "family": f, "inputs": "q, qd, qdd", "status": "ok",
                "val_loss": "0.1", "test_loss": "0.1", "rmse": r, "nmse": "0.1"}
               for m, f, r in (("rnea", "analytic", "0.25"), ("seed-tau-mlp", "seed-net", MLP_RMSE))]
REPORT_META = {"bench_report": 1, "wall_seconds": 60.0, "scenarios": {"s": "data/s"}, "skipped": [],
               "requested": ["s / joint_torque / rnea", "s / joint_torque / seed-tau-mlp"],
               "invocations": [{"started": "2026-12-04T10:00:00Z", "finished": "2026-12-04T10:01:00Z",
                                "wall_seconds": 60.0, "rows": 2}],
               "profile": {"name": "data", "scenarios": ["data/s"], "generator_profile": "quick", "seed": 0,
                           "recipe": "budget", "train": {}, "notes": [], "scenario_overrides": {}},
               "report_files": ["README.md", "joint_torque.md", "rmse_by_family_joint_torque.png"]}


def _report_folder(here: Path) -> Path:
    """A report folder as the bench leaves it (no predictions.h5: the digest vouches for the rows), its own
    README, a table and a recorded figure, and the user's files beside them."""
    import json

    from hybrid_dyn.bench.integrity import results_digest
    from hybrid_dyn.bench.results import write_results

    here.mkdir(parents=True)
    write_results(here / "results.csv", REPORT_ROWS)
    meta = copy.deepcopy(REPORT_META)
    meta["results_digest"] = results_digest(here / "results.csv", meta)
    (here / "run.json").write_text(json.dumps(meta))
    for name in meta["report_files"]:
        (here / name).write_bytes(b"the report's")
    for name, data in USER_FILES.items():
        (here / name).write_bytes(data)
    return here


def _mutate_report(here: Path, rng) -> str:
    """One random change of a report folder, as a user's hand or a broken copy makes it (none where an
    earlier change left nothing to change: a file deleted, a folder, a JSON list)."""
    try:
        return _change_report(here, rng)
    except (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError):
        return "none"


def _change_report(here: Path, rng) -> str:
    import json

    from hybrid_dyn.bench.integrity import run_digest

    kind = int(rng.integers(9))
    target = here / str(rng.choice(["run.json", "results.csv"]))
    if kind == 0:
        name = str(rng.choice(["run.json", "results.csv", "README.md", "joint_torque.md"]))
        (here / name).unlink()
        return f"deleted {name}"
    if kind == 1:
        target.write_bytes(bytes(rng.integers(0, 256, 200, dtype=np.uint8)))
        return f"random bytes in {target.name}"
    if kind == 2:
        text = target.read_bytes()
        target.write_bytes(text[: int(rng.integers(len(text)))])
        return f"truncated {target.name}"
    if kind in (3, 4):  # results.csv edited: a cell, or the table's shape
        lines = (here / "results.csv").read_text().splitlines()
        i = int(rng.integers(1, len(lines)))
        if kind == 3:
            cells = lines[i].split(",")
            j = int(rng.integers(len(cells)))
            cells[j] = str(rng.choice(["0.0123", "", "abc", "nan", "-1", "ok", "failed", "s", "rnea", "1e400"]))
            lines[i] = ",".join(cells)
            did = f"results.csv line {i + 1} cell {j} = {cells[j]!r}"
        else:
            change = int(rng.integers(4))
            if change == 0:
                lines[i] += ",extra"
            elif change == 1:
                lines.pop(i)
            elif change == 2:
                lines.insert(i, lines[i])
            else:
                lines[0] = lines[0].replace("rmse", "RMSE", 1)
            did = f"results.csv shape change {change} at line {i + 1}"
        (here / "results.csv").write_text("\n".join(lines) + "\n")
        return did
    if kind == 5:
        doc = [{"profile": "mine"}, {"profile": "mine", "lr": 0.01}, {"bench_report": 1}, [], "x"][int(rng.integers(5))]
        (here / "run.json").write_text(json.dumps(doc))
        return f"a user's run.json: {doc!r}"
    if kind == 6:
        name = str(rng.choice(["run.json", "results.csv"]))
        (here / name).unlink()
        (here / name).mkdir()
        return f"{name} is a folder"
    meta = json.loads((here / "run.json").read_text())
    if kind == 7:  # a user's files put on the record by hand (run.json not re-digested: refused)
        meta["report_files"] = [*meta["report_files"], *USER_FILES, "../notes.txt", "run.json"][: int(rng.integers(4, 9))]
        (here / "run.json").write_text(json.dumps(meta))
        return f"report_files = {meta['report_files']}"
    key = str(rng.choice(sorted(k for k in meta if k not in ("results_digest", "report_files"))))
    meta[key] = copy.deepcopy(ODD[rng.integers(len(ODD))])
    if rng.random() < 0.5:  # re-digested, as a careful editor would: the reader must still not crash
        meta["results_digest"]["run"] = run_digest(meta)
    (here / "run.json").write_text(json.dumps(meta, allow_nan=True))
    return f"run.json {key} = {meta[key]!r}"


def _user_files_kept(here: Path, what: str) -> None:
    kept = {n: (here / n).read_bytes() for n in USER_FILES if (here / n).is_file()}
    assert kept == USER_FILES, f"{what}: the user's files in {here.name} changed: {sorted(set(USER_FILES) - set(kept))}"


@pytest.mark.slow  # 150 cases of compare and report on mutated folders, figures stubbed: ~10 s
def test_fuzzed_report_folders_end_in_a_report_or_one_error(tmp_path, monkeypatch, capsys):
    """``hybrid-dyn report`` and ``compare`` (with ``--out``) on report folders changed at random: a README or
    a comparison showing only what the bench wrote, or one HybridDynError; never a traceback, and the user's
    files in the folder and at ``--out`` are never written over or deleted."""
    from hybrid_dyn.bench import report as report_mod
    from hybrid_dyn.cli import main as cli_main
    from hybrid_dyn.outputs import write_own_text

    def figures(out_dir, rows, preds, seed=0):  # the bars' file, drawn in milliseconds
        (Path(out_dir) / "rmse_by_family_joint_torque.png").write_bytes(b"\x89PNG")
        return ["rmse_by_family_joint_torque.png"]

    monkeypatch.setattr(report_mod, "_figures", figures)
    monkeypatch.setattr(report_mod, "learning_curve_figures", lambda *a, **k: [])
    good = _report_folder(tmp_path / "good")
    rng = np.random.default_rng(SPEC_SEED + 3)
    counts = {"report ok": 0, "report refused": 0, "compare ok": 0, "compare refused": 0}
    for case in range(150):
        here = _report_folder(tmp_path / f"f{case:03d}")
        # one case in six unchanged (what must pass), the others changed once or twice
        did = [_mutate_report(here, rng) for _ in range(int(rng.choice([0, 1, 1, 1, 1, 2])))]
        what = f"report folder case {case} ({'; '.join(did) or 'unchanged'})"
        # --out: new, the user's file, a file of compare's own, one edited since, or a folder
        out, state = tmp_path / f"notes{case:03d}.md", int(rng.choice(5, p=[0.4, 0.15, 0.25, 0.1, 0.1]))
        if state == 1:
            out.write_text("# my notes\n")
        elif state in (2, 3):
            write_own_text(out, "an earlier comparison\n", "compare")
            if state == 3:
                out.write_text(out.read_text() + "my conclusion\n")
        elif state == 4:
            out.mkdir()
        before_out = out.read_bytes() if out.is_file() else None

        def compare():
            capsys.readouterr()
            rc = cli_main(["compare", str(here), str(good), "--out", str(out)])
            shown, err = capsys.readouterr()
            assert rc in (0, 2), f"{what}: compare exit status {rc}"
            if rc == 2:
                assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, f"{what}: {err}"
                return "refused"
            for text in (shown, out.read_text()):  # what it shows is what the bench wrote, in both reports
                assert f"| seed-tau-mlp | seed-net | {float(MLP_RMSE):.3f} |" in text, f"{what}: {text}"
            return "ok"

        status, result = _check_outcome(compare, what + f", --out state {state}")
        outcome = result if status == "ok" else "refused"
        counts[f"compare {outcome}"] += 1
        if state in (1, 3):  # the user's: never replaced
            assert out.read_bytes() == before_out, f"{what}: --out state {state} was written over"
            assert outcome == "refused", f"{what}: --out state {state} accepted"
        _user_files_kept(here, what)
        status, _ = _check_outcome(lambda: report_mod.rebuild_report(here, log=lambda m: None), what)
        counts[f"report {status}"] += 1
        if status == "ok":
            assert (here / "README.md").read_text().startswith("# Benchmark report"), what
        _user_files_kept(here, what)
    _user_files_kept(good, "the unchanged report")
    assert all(v >= 5 for v in counts.values()), counts
    print(f"report folder fuzz: {counts}")


def _snapshot(root: Path) -> dict:
    """Every file under ``root`` (or ``root`` itself, a file) and its bytes; folders by name."""
    if root.is_file():
        return {".": root.read_bytes()}
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else "folder") for p in root.rglob("*")} \
        if root.is_dir() else {}


@pytest.mark.slow  # 150 studies with their benches stubbed: a few seconds
def test_fuzzed_study_folders_end_in_a_summary_or_one_error(tmp_path, monkeypatch):
    """``study --out`` on folders holding a random mix of the study's own files and a user's: a summary where
    the folder is the study's (its summary JSON names it, or it holds only the variants' bench reports),
    else one OutputPathError before any work; the user's files are never written over or deleted."""
    import json

    from hybrid_dyn.bench import studies as studies_mod
    from hybrid_dyn.bench.studies import Overrides, Study, run_study
    from hybrid_dyn.errors import OutputPathError

    study = Study("fuzz-study", "seed-sim", "a fuzz", rows=("rnea",), base=Overrides(data={"n_instances": 8}),
                  variants={"v": Overrides(train={"lr": 1e-3})}, keep_variant_reports=True)
    ran = []

    def variant(study, name, rows, where, reference_report=None, **run_args):
        ran.append(name)
        return [], [where]

    monkeypatch.setattr(studies_mod, "_run_variant", variant)
    bench_meta = json.dumps({"bench_report": 1, "profile": {"name": "x"}})
    entries = {  # name -> (how to make it, whether it proves nothing of the user's: the study's own)
        "README.md": (lambda p: p.write_text("# my notes\n"), False),
        "notes.txt": (lambda p: p.write_text("mine"), False),
        "fuzz-study.json": (lambda p: p.write_text('{"study": "fuzz-study", "panels": []}'), True),
        "fuzz-study.json ": (lambda p: p.write_text('{"study": "other"}'), False),  # another study's mark
        "fuzz-study.json  ": (lambda p: p.write_text('{"study": '), False),  # truncated
        "fuzz-study.json   ": (lambda p: p.mkdir(), False),  # a folder of that name
        "data_scaling.json": (lambda p: p.write_text('{"study": "fuzz-study"}'), False),  # not this kind's file
        "v": (lambda p: (p.mkdir(), (p / "run.json").write_text(bench_meta)), True),  # a variant's bench report
        "base ": (lambda p: (p.mkdir(), (p / "run.json").write_text('{"profile": "mine"}')), False),
        "v ": (lambda p: p.mkdir(), False),  # a variant's name, no report in it
        ".v.lock": (lambda p: p.write_text(""), True),
    }
    rng = np.random.default_rng(SPEC_SEED + 4)
    counts = {"ok": 0, "refused": 0}
    for case in range(150):
        out = tmp_path / f"s{case:03d}" / "out"
        out.parent.mkdir()
        picked = {str(n).strip(): str(n) for n in rng.choice(sorted(entries), int(rng.integers(0, 4)))}
        names = sorted(picked.values())  # one entry per file name
        if rng.random() < 0.9:
            out.mkdir()
            for name in names:
                entries[name][0](out / name.strip())  # trailing blanks: the variants of one name
        elif rng.random() < 0.5:
            out.write_text("a user's file where the folder goes")
            names = ["(a file)"]
        else:
            names = []
        what = f"study folder case {case} ({', '.join(names) or 'new' if out.exists() else 'absent'})"
        before = _snapshot(out)
        marked = "fuzz-study.json" in names
        own = not out.exists() or (out.is_dir() and (marked or all(entries[n][1] for n in names)))
        ran.clear()
        status, result = _check_outcome(lambda: run_study(study, tmp_path / "report", out,
                                                          work_root=tmp_path / "runs", log=lambda m: None), what)
        counts[status] += 1
        after = _snapshot(out)
        if own:
            assert status == "ok", f"{what}: its own folder refused: {result}"
            assert json.loads((out / "fuzz-study.json").read_text())["study"] == "fuzz-study", what
            changed = {k for k in before if after.get(k) != before[k]}
            assert changed <= {"README.md", "fuzz-study.json"} and (marked or "README.md" not in before), \
                f"{what}: changed {changed}"
        else:
            assert status == "refused" and isinstance(result, OutputPathError), f"{what}: {status} {result}"
            assert after == before and ran == [], f"{what}: refused, but work began or files changed"
    assert counts["ok"] >= 20 and counts["refused"] >= 20, counts
    print(f"study folder fuzz: {counts}")
