"""Input checks before any output exists (issue 28): URDF structure, parameter files, split fractions.

Each case is one the issue found breaking: a hang, a traceback or a silently wrong dataset. The
expected answer is a one-line HybridDynError naming the problem, and nothing written.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.description import RobotDescriptionError, read_param_file, resolve_robot, robots_dir
from hybrid_dyn.errors import HybridDynError
from hybrid_dyn.input_checks import inertial_problems, split_problems, urdf_tree_problems
from timelimit import time_limit

LINK = '<link name="{0}"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>' \
       '</inertial></link>'
JOINT = '<joint name="{0}" type="revolute"><parent link="{1}"/><child link="{2}"/><axis xyz="0 0 1"/>' \
        '<limit lower="-1" upper="1" effort="10" velocity="1"/></joint>'


def urdf(tmp_path, links, joints, name="r.urdf"):
    path = tmp_path / name
    path.write_text("<robot name='r'>" + "".join(LINK.format(n) for n in links)
                    + "".join(JOINT.format(*j) for j in joints) + "</robot>")
    return path


# ------------------------------------------------------------------ finding 1: a joint cycle
def test_a_urdf_with_a_joint_cycle_is_refused_at_once_not_walked_forever(tmp_path):
    """Finding 1: joints a->b and b->a hung in describe_urdf's chain with growing memory."""
    cyc = urdf(tmp_path, ["base", "a", "b"], [("j0", "base", "a"), ("j1", "a", "b"), ("j2", "b", "a")], "cyc.urdf")
    with time_limit(10, "resolving a cyclic URDF"), pytest.raises(RobotDescriptionError, match="not a tree of links"):
        resolve_robot(str(cyc))
    # A cycle with no root at all (every link a child): named as such.
    ring = urdf(tmp_path, ["a", "b"], [("j1", "a", "b"), ("j2", "b", "a")], "ring.urdf")
    with time_limit(10, "resolving a ring URDF"), pytest.raises(RobotDescriptionError, match="0 root links"):
        resolve_robot(str(ring))


def test_the_bench_and_import_refuse_a_cyclic_robot_before_reading_data(tmp_path):
    from hybrid_dyn.bench.profiles import profile_for_data
    from hybrid_dyn.data.importer import LogSpec

    cyc = urdf(tmp_path, ["base", "a", "b"], [("j0", "base", "a"), ("j1", "a", "b"), ("j2", "b", "a")], "cyc.urdf")
    with time_limit(10, "bench profile"), pytest.raises(RobotDescriptionError, match="joint cycle|child of two"):
        profile_for_data([tmp_path / "no-data"], robot=str(cyc))
    with time_limit(10, "import spec"), pytest.raises(RobotDescriptionError, match="joint cycle|child of two"):
        LogSpec(name="x", files=[tmp_path / "no.csv"], columns={"q": "1", "tau_m": "2"}, robot=str(cyc),
                sample_rate_hz=100.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cyc.urdf"]  # nothing written


@pytest.mark.parametrize("text, message", [
    # finding 6: a joint without <child> was an AttributeError
    ("<robot><link name='a'/><link name='b'/><joint name='j' type='fixed'><parent link='a'/></joint></robot>",
     "joint 'j' has no <child link"),
    ("<robot><link name='a'/><link name='b'/><joint name='j' type='fixed'><child link='b'/></joint></robot>",
     "joint 'j' has no <parent link"),
    ("<robot><link name='a'/><joint name='j' type='fixed'><parent link='a'/><child link='zz'/></joint></robot>",
     "child link 'zz', which is not a <link>"),
    ("<robot><link name='a'/><link name='a'/></robot>", "defined more than once"),
    ("<robot><link name='a'/><link name='b'/></robot>", "2 root links"),
    ("<robot><link name='a'/><link name='b'/><link name='c'/><joint name='j1' type='fixed'><parent link='a'/>"
     "<child link='c'/></joint><joint name='j2' type='fixed'><parent link='b'/><child link='c'/></joint></robot>",
     "child of two joints"),
])
def test_urdf_structure_problems_are_one_line_errors(tmp_path, text, message):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    for call in (lambda: resolve_robot(str(path)), lambda: hd.description.read_tool(path)):
        with time_limit(10), pytest.raises(RobotDescriptionError, match=message) as err:
            call()
        assert "\n" not in str(err.value)


def test_every_shipped_and_example_robot_urdf_is_a_tree():
    """The check refuses nothing the toolkit ships (its robots and the arms of example-robot-data load)."""
    import xml.etree.ElementTree as ET

    from hybrid_dyn.description import available_robots, load_spec

    for name in available_robots():
        assert urdf_tree_problems(ET.parse(load_spec(name).urdf_path).getroot()) == [], name
    assert hd.load_robot("ur10").nv == 6 and hd.load_robot("panda[tool=none]").nv == 7


# ------------------------------------------------------------------ parameter files
@pytest.mark.parametrize("inertia, message", [
    ([-0.01, 0, 0, 0.01, 0, 0.01], "not positive semi-definite"),
    ([0.01, 0.02, 0, 0.01, 0, 0.01], "not positive semi-definite"),  # off-diagonal larger than the diagonal
    ([0.001, 0, 0, 0.001, 0, 0.01], "triangle inequality"),
    ([0.0, 0, 0, 0.01, 0, 0.01], "singular"),
])
def test_a_parameter_file_that_is_no_rigid_body_is_refused(tmp_path, inertia, message):
    """Finding 7: a negative inertia was accepted."""
    f = tmp_path / "p.json"
    f.write_text(json.dumps({"links": [{"name": "panda_link1", "mass": 2.0, "com": [0, 0, 0], "inertia": inertia}]}))
    with pytest.raises(RobotDescriptionError, match=f"panda_link1: not a rigid body: .*{message}"):
        read_param_file(f)
    with pytest.raises(RobotDescriptionError, match=message):
        hd.load_robot("panda", params=f)


def test_the_inertia_check_agrees_with_a_sampled_body():
    """Reference: the inertia of point masses (always a rigid body) passes; the same with one moment
    pushed past the sum of the other two fails, as does its negation."""
    rng = np.random.default_rng(0)
    for _ in range(50):
        pts, m = rng.normal(size=(6, 3)), rng.uniform(0.1, 1.0, 6)
        com = (m[:, None] * pts).sum(0) / m.sum()
        r = pts - com
        inertia = sum(mi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for mi, ri in zip(m, r))
        six = [inertia[0, 0], inertia[0, 1], inertia[0, 2], inertia[1, 1], inertia[1, 2], inertia[2, 2]]
        assert inertial_problems(m.sum(), six) == []
        w, v = np.linalg.eigh(inertia)
        w[2] = 1.2 * (w[0] + w[1])
        broken = v @ np.diag(w) @ v.T
        six = [broken[0, 0], broken[0, 1], broken[0, 2], broken[1, 1], broken[1, 2], broken[2, 2]]
        assert "triangle" in " ".join(inertial_problems(m.sum(), six))
        assert "semi-definite" in " ".join(inertial_problems(m.sum(), [-x for x in six]))


def test_the_shipped_manufacturer_set_says_why_it_breaks_the_triangle_inequality():
    """The manufacturer's published link 4 breaks the triangle inequality; the file says it is kept as
    published, and without that note it is refused."""
    path = robots_dir() / "params" / "panda_franka_official_inertials.json"
    doc = json.loads(path.read_text())
    link4 = next(ln for ln in doc["links"] if ln["name"] == "panda_link4")
    assert "violated as published" in link4["triangle_inequality"]
    assert len(read_param_file(path)) == len(doc["links"])
    assert "triangle" in " ".join(inertial_problems(link4["mass"], link4["inertia"]))


# ------------------------------------------------------------------ finding 4: split fractions
@pytest.mark.parametrize("split, message", [
    ({"test_frac": 0}, "test_frac must lie strictly between 0 and 1"),
    ({"test_frac": -0.5}, "test_frac must lie strictly between 0 and 1"),
    ({"test_frac": 1}, "test_frac must lie strictly between 0 and 1"),
    ({"test_frac": 2}, "test_frac must lie strictly between 0 and 1"),
    ({"val_frac": 1.0}, "val_frac must lie strictly between 0 and 1"),
    ({"test_frac": "0.2"}, "test_frac must be a number, got '0.2'"),
    ({"val_frac": float("nan")}, "val_frac must be a number"),
    ({"seed": "abc"}, "split seed must be a non-negative integer, got 'abc'"),
    ({"seed": -1}, "split seed must be a non-negative integer"),
    ({"seed": True}, "split seed must be a non-negative integer"),
])
def test_bad_split_settings_are_refused_in_one_line_before_the_log_is_read(tmp_path, split, message):
    from hybrid_dyn.data.importer import LogSpecError, spec_from_dict

    doc = {"name": "x", "robot": "panda", "source": {"files": ["missing.csv"]}, "time": {"sample_rate_hz": 100},
           "columns": {"q": "1-7", "tau_m": "8-14"}, "split": split}
    with pytest.raises(LogSpecError, match=message) as err:
        spec_from_dict(doc, base_dir=tmp_path)
    assert "\n" not in str(err.value)
    assert split_problems(0, 0.2, 0.2) == []


def test_split_fractions_that_leave_a_split_empty_are_refused_by_import_and_bench(tmp_path, capsys):
    """Finding 4: test_frac 0.99 left no training split (the bench failed in train_split_stats after writing
    run.json); n_blocks = 2 left val and test empty (import only warns: two trajectories cannot make three
    splits), and every bench row then failed with the same numpy message."""
    from hybrid_dyn.cli import main as cli_main
    from test_bench_data import write_log

    spec = write_log(tmp_path / "logs", n=200)
    text = spec.read_text()
    spec.write_text(text.replace("seed = 0\n", "seed = 0\ntest_frac = 0.99\n"))
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "the train, val splits are empty" in err and "test_frac = 0.99" in err
    assert not (tmp_path / "a").exists()
    spec.write_text(text.replace("n_blocks = 10", "n_blocks = 2"))
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "b")]) == 0
    assert "only 2 trajectories" in capsys.readouterr().out
    out = tmp_path / "report"
    assert cli_main(["bench", "--data", str(tmp_path / "b"), "--out", str(out), "--rows", "rnea",
                     "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err
    assert "the val, test splits are empty" in err and str(tmp_path / "b") in err
    assert not out.exists() and not (tmp_path / "runs").exists()


# ------------------------------------------------------------ findings 5 and 7: the bench's robot, params, rows
@pytest.fixture(scope="module")
def panda_log(tmp_path_factory):
    """A tiny 7-joint Panda log, imported (10 blocks, split 6/2/2)."""
    from hybrid_dyn.cli import main as cli_main
    from test_bench_data import write_log

    tmp = tmp_path_factory.mktemp("panda-log")
    spec = write_log(tmp / "logs", n=200)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp / "log")]) == 0
    return tmp / "log"


@pytest.mark.parametrize("extra, message", [
    # finding 5: --robot ur5 on a 7-joint log wrote the report, then every analytic row failed
    (["--robot", "ur5"], "robot 'ur5' has 6 joints but dataset"),
    # finding 7: --params nonexist was refused only after --out was created
    (["--params", "nonexist"], "no parameter set 'nonexist'"),
    (["--params", "nonexist.json"], "parameter file not found"),
    # finding 7: --rows base-wrench on a log without a base wrench: '0/0 rows ok', exit 0
    (["--rows", "base-wrench"], "none of the selected rows applies to the data (base-wrench on my-panda: needs"),
])
def test_the_bench_refuses_what_it_cannot_score_before_the_report_folder_exists(panda_log, tmp_path, capsys, extra,
                                                                                 message):
    from hybrid_dyn.cli import main as cli_main

    args = ["bench", "--data", str(panda_log), "--out", str(tmp_path / "report"),
            "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]
    if "--rows" not in extra:
        args += ["--rows", "rnea"]
    capsys.readouterr()
    with time_limit(60, "bench"):
        assert cli_main(args + extra) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []  # no report folder, no lock file, no caches


def test_a_bad_parameter_file_is_refused_by_a_named_profile_before_any_data(tmp_path):
    from hybrid_dyn.bench.profiles import get_profile

    f = tmp_path / "p.json"
    f.write_text(json.dumps({"links": [{"name": "panda_link1", "mass": 2.0, "com": [0, 0, 0],
                                        "inertia": [-0.01, 0, 0, 0.01, 0, 0.01]}]}))
    import dataclasses

    with pytest.raises(HybridDynError, match="not positive semi-definite"):
        dataclasses.replace(get_profile("quick"), params=str(f))


@pytest.mark.slow  # imports a log and runs the bench's rnea row
def test_an_import_warning_reaches_the_bench_report(tmp_path, capsys):
    """Finding 7: the import's warning that the time column fits 'ms' never reached the bench report,
    which then showed RNEA at 0.552 Nm against 4e-6 with the right unit."""
    from hybrid_dyn.cli import main as cli_main
    from test_bench_data import write_log

    spec = write_log(tmp_path / "logs", n=200)
    log = tmp_path / "logs" / "log.csv"
    lines = log.read_text().splitlines()
    lines[1:] = [",".join([repr(float(row.split(",")[0]) * 1000)] + row.split(",")[1:]) for row in lines[1:]]
    log.write_text("\n".join(lines) + "\n")  # time in ms, the spec says s
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 0
    warning = "the time column fits the unit 'ms', not the declared 's'"
    assert warning in capsys.readouterr().out
    out = tmp_path / "report"
    cli_main(["bench", "--data", str(tmp_path / "ds"), "--out", str(out), "--rows", "rnea",
              "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")])
    assert warning in capsys.readouterr().out
    readme = (out / "README.md").read_text()
    assert "**import warning**" in readme and warning in readme
    assert warning in json.loads((out / "run.json").read_text())["datasets"]["my-panda"]["import_warnings"][0]


@pytest.mark.slow  # trains a tiny net
def test_a_bench_waits_for_a_model_another_bench_is_training_in_a_shared_runs_folder(panda_log, tmp_path):
    """Finding 7: two benches with different --out sharing runs/: the second one's row failed on the
    model lock. Here another run holds that model's lock for 3 s; the bench waits, then trains it."""
    import threading
    import time

    from hybrid_dyn.bench.runner import run_bench, work_dir
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.outputs import output_lock
    from test_bench_data import tiny_profile

    profile = tiny_profile([panda_log])
    profile = type(profile)(**{**profile.__dict__, "rows": ("seed-tau-mlp",)})
    model_dir = work_dir(profile, "my-panda", load_dataset(panda_log), tmp_path / "runs") / "models" / "seed-tau-mlp"
    held, release = threading.Event(), threading.Event()

    def other_run():
        with output_lock(model_dir, "model folder"):
            held.set()
            release.wait(3.0)

    other = threading.Thread(target=other_run)
    other.start()
    held.wait(10)
    t0 = time.perf_counter()
    try:
        with time_limit(120, "bench"):
            rows = run_bench(profile, tmp_path / "report", data_root=tmp_path / "data", work_root=tmp_path / "runs",
                             log=lambda m: None)
    finally:
        release.set()
        other.join()
    assert [(r["model"], r["status"]) for r in rows] == [("seed-tau-mlp", "ok")], rows
    assert time.perf_counter() - t0 >= 2.5  # it waited for the other run's lock
    assert (model_dir / "config.json").is_file()


def test_every_command_leaves_a_users_folder_alone(panda_log, tmp_path, capsys):
    """Ownership by proof (issue 28): a folder holding a user's files that happen to carry the toolkit's
    file names (run.json with a 'profile' key, config.json, generator.json, manifest.json) is refused by
    bench, report, generate, train and import alike, and every file is left as it was."""
    from hybrid_dyn.cli import main as cli_main

    user = tmp_path / "mine"
    user.mkdir()
    files = {"run.json": json.dumps({"profile": "my-experiment", "lr": 0.01}), "README.md": "# notes\n",
             "results.csv": "epoch,loss\n1,0.5\n", "config.json": json.dumps({"lr": 0.01}),
             "generator.json": json.dumps({"profile": "x"}), "manifest.json": json.dumps({"format": "mine"})}
    for name, text in files.items():
        (user / name).write_text(text)
    spec = panda_log.parent / "logs" / "spec.toml"
    roots = ["--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]
    commands = {
        "bench": ["bench", "--data", str(panda_log), "--out", str(user), "--rows", "rnea", *roots],
        "report": ["report", str(user)],
        "generate": ["generate", "--scenario", "paper-noext", "--out", str(user), "--quiet"],
        "train": ["train", "--data", str(panda_log), "--preset", "seed-tau-mlp", "--out", str(user), "--max-epochs", "1"],
        "import": ["import", "--spec", str(spec), "--out", str(user), "--overwrite"],
    }
    seen = {}
    for name, argv in commands.items():
        capsys.readouterr()
        with time_limit(60, name):
            assert cli_main(argv) == 2, name
        err = capsys.readouterr().err
        assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, (name, err)
        assert {p.name: p.read_text() for p in user.iterdir()} == files, name
        seen[name] = err
    # Each names the folder as a user's, not as a dataset or model of another run.
    assert all("refusing to replace" in e and "not written by hybrid-dyn" in e for e in seen.values()), seen


def test_a_bench_that_ran_no_row_does_not_exit_0(tmp_path, capsys, monkeypatch):
    """Finding 7's '0/0 rows ok, exit 0', for a named profile: every real log missing, so every scenario
    is skipped with its reason; no row ran, which is no result (exit 1), and the report says why."""
    from hybrid_dyn.cli import main as cli_main

    monkeypatch.setenv("HYBRID_DYN_REAL_LOGS", str(tmp_path / "no-logs"))
    out = tmp_path / "report"
    with time_limit(120, "bench"):
        code = cli_main(["bench", "--profile", "real", "--out", str(out), "--data-root", str(tmp_path / "data"),
                         "--work-root", str(tmp_path / "runs")])
    assert "0/0 rows ok" in capsys.readouterr().out and code == 1
    assert "## Rows not run" in (out / "README.md").read_text()
