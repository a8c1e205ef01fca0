"""The robot registry ROBOTS: a robot is a name declared once, with its description TOML or as data-only."""
import json
import os
import re
import subprocess
import sys
import warnings

import pytest

import hybrid_dyn as hd
from hybrid_dyn.description import ROBOTS, RobotDeclaration, RobotDescriptionError, has_description, load_spec
from hybrid_dyn.description.robots import declare_robot_folder
from hybrid_dyn.resources import resource_dir

from helpers import REPO


def _toy_toml(folder, name="toy-arm"):
    """A copy of the shipped UR5 description under another name (same URDF, frames and limits)."""
    text = (resource_dir("robots") / "ur5.toml").read_text()
    assert 'name = "ur5"' in text
    path = folder / f"{name}.toml"
    path.write_text(text.replace('name = "ur5"', f'name = "{name}"'))
    return path


@pytest.fixture
def toy_robot(tmp_path):
    robot = ROBOTS.register(RobotDeclaration(name="toy-arm", toml=_toy_toml(tmp_path)))
    yield robot
    ROBOTS.unregister(robot.name)


def test_every_shipped_description_is_declared_and_no_declaration_lacks_its_file():
    """The catalogue against the package data's folder, read here: each ``*.toml`` there is a declared robot."""
    shipped = {p.stem: p for p in resource_dir("robots").glob("*.toml")}
    described = {r.name: r.toml for r in ROBOTS.where(data_only=False)}
    assert {"panda", "ur5", "xarm7", "kuka-lwr", "baxter"} <= set(shipped)
    assert {n: p.resolve() for n, p in shipped.items()} == {n: p.resolve() for n, p in described.items()}
    assert {"sarcos", "unknown"} <= set(ROBOTS.names(data_only=True))
    assert all(r.toml is None and not has_description(r.name) for r in ROBOTS.where(data_only=True))


def test_a_registered_robot_loads_by_name_and_is_listed_until_unregistered(toy_robot, ur5, capsys):
    from hybrid_dyn.analytic.cli import cmd_robots

    robot = hd.load_robot("toy-arm")
    # Its TOML is the UR5's: the same URDF and frames make the same model.
    assert robot.name == "toy-arm" and robot.nv == ur5.nv == 6
    assert robot.total_mass == pytest.approx(ur5.total_mass, abs=0, rel=0)
    assert "toy-arm" in list(ROBOTS.names(data_only=False)) and has_description("toy-arm")
    assert hd.load_robot("toy-arm[payload=1.0@0,0,0]").total_mass == pytest.approx(ur5.total_mass + 1.0)
    assert cmd_robots(None) == 0
    assert "toy-arm " in capsys.readouterr().out
    ROBOTS.unregister("toy-arm")
    with pytest.raises(RobotDescriptionError, match="unknown robot 'toy-arm'.*panda"):
        hd.load_robot("toy-arm")
    ROBOTS.register(toy_robot)  # for the fixture's own unregister


def test_a_data_only_robot_is_a_name_without_a_model():
    robot = ROBOTS.register(RobotDeclaration("toy-blackbox", summary="an arm with logs and no URDF"))
    try:
        assert robot.data_only and not has_description("toy-blackbox")
        with pytest.raises(RobotDescriptionError, match="known for data only"):
            hd.load_robot("toy-blackbox")
        with pytest.raises(RobotDescriptionError, match="known for data only"):
            load_spec("toy-blackbox")
    finally:
        ROBOTS.unregister("toy-blackbox")


def test_bad_declarations_are_refused_naming_the_problem(tmp_path):
    with pytest.raises(RobotDescriptionError, match="'panda' is declared twice"):
        ROBOTS.register(RobotDeclaration("panda", _toy_toml(tmp_path, "panda")))
    with pytest.raises(RobotDescriptionError, match=r"a \.toml file"):
        RobotDeclaration("toy-arm", tmp_path / "toy-arm.urdf")
    with pytest.raises(RobotDescriptionError, match="non-empty text"):
        RobotDeclaration("")
    ROBOTS.register(RobotDeclaration("other-name", _toy_toml(tmp_path, "toy-arm")))
    try:
        with pytest.raises(RobotDescriptionError, match="describes 'toy-arm': the two names must agree"):
            load_spec("other-name")
    finally:
        ROBOTS.unregister("other-name")
    (tmp_path / "data_only.toml").write_text('robots = ["my-arm"]\n')
    before = dict(ROBOTS)
    with pytest.raises(RobotDescriptionError, match=r"data_only.toml: \[robots\] is a table"):
        declare_robot_folder(tmp_path)
    assert dict(ROBOTS) == before  # nothing of the folder declared
    ROBOTS.register(RobotDeclaration("gone", tmp_path / "gone.toml"))
    try:
        with pytest.raises(RobotDescriptionError, match="no description file"):
            load_spec("gone")
    finally:
        ROBOTS.unregister("gone")


def test_the_folder_hybrid_dyn_robots_names_adds_its_descriptions_and_data_only_names(tmp_path):
    """In a fresh process (the variable is read when the catalogue is imported): the folder's robots are
    declared beside the shipped ones, and its copy of a shipped description takes that name's place."""
    _toy_toml(tmp_path)
    (tmp_path / "ur5.toml").write_text((resource_dir("robots") / "ur5.toml").read_text())
    (tmp_path / "data_only.toml").write_text('[robots]\nmy-arm = "an arm of my lab"\n')
    code = ("import json; from hybrid_dyn.description import ROBOTS\n"
            "print(json.dumps({r.name: str(r.toml) for r in ROBOTS.values()}))")
    env = {**os.environ, "HYBRID_DYN_ROBOTS": str(tmp_path), "PYTHONPATH": str(REPO / "src")}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert got["toy-arm"] == str(tmp_path / "toy-arm.toml") and got["ur5"] == str(tmp_path / "ur5.toml")
    assert got["my-arm"] == "None" and got["panda"] == str(resource_dir("robots") / "panda.toml")


def test_the_dart_contract_runs_on_a_robot_declared_with_no_test_edit(tmp_path):
    """The DART-against-Pinocchio tests are parametrized over ROBOTS: a robot declared in the folder
    ``$HYBRID_DYN_ROBOTS`` names is collected and checked by them (a fresh pytest process)."""
    _toy_toml(tmp_path)
    env = {**os.environ, "HYBRID_DYN_ROBOTS": str(tmp_path), "PYTHONPATH": str(REPO / "src")}
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:xdist", "-p", "no:cacheprovider",
                          "tests/analytic/test_dynamics_vs_dart.py", "-k", "toy-arm"],
                         cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    assert re.search(r"\b3 passed", out.stdout), out.stdout[-2000:]


UR10 = """name = "ur10"
urdf = "ur_description/urdf/{urdf}"
tool_frame = "tool0"
flange = "tool0"
base_sensor_frame = "base_link"
home = [0.0, -1.2, 1.5, -1.9, -1.57, 0.0]
encoder_resolution = 2.4e-5
rated_payload_kg = 10.0
"""


def test_a_toml_dropped_in_the_shipped_folder_is_a_robot_with_no_list_to_edit(tmp_path):
    """In a copy of the package: ``resources/robots/ur10.toml`` is declared by its file alone, and ``ur10`` is then
    that description (base_link, its encoders, its rated payload), not example-robot-data's bare URDF."""
    import shutil

    shutil.copytree(REPO / "src" / "hybrid_dyn", tmp_path / "hybrid_dyn",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    (tmp_path / "hybrid_dyn" / "resources" / "robots" / "ur10.toml").write_text(UR10.format(urdf="ur10_robot.urdf"))
    code = ("import json, warnings; warnings.simplefilter('error')\n"
            "import hybrid_dyn as hd; from hybrid_dyn.description import ROBOTS\n"
            "s = hd.load_robot('ur10').spec\n"
            "print(json.dumps([hd.__file__, list(ROBOTS.names(data_only=False)), s.base_sensor_frame,"
            " s.encoder_resolution, s.rated_payload_kg]))")
    env = {k: v for k, v in os.environ.items() if k != "HYBRID_DYN_ROBOTS"}
    env["PYTHONPATH"] = str(tmp_path)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120,
                         cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    where, names, frame, resolution, payload = json.loads(out.stdout)
    assert where.startswith(str(tmp_path)) and "ur10" in names
    assert (frame, resolution, payload) == ("base_link", 2.4e-5, 10.0)


def test_a_robot_shadowing_an_example_robot_data_arm_warns_once(tmp_path, monkeypatch):
    """``ur10`` declared on the UR5's URDF means another arm than example-robot-data's ``ur10``: said, once; the
    same name on the UR10's own URDF (a fuller description of that arm) says nothing."""
    from hybrid_dyn.description import names

    monkeypatch.setattr(names, "_SHADOWS_CHECKED", set())
    (tmp_path / "ur10.toml").write_text(UR10.format(urdf="ur5_robot.urdf"))
    ROBOTS.register(RobotDeclaration("ur10", tmp_path / "ur10.toml"))
    try:
        with pytest.warns(UserWarning, match=r"robot 'ur10' .* shadows example-robot-data's 'ur10'"):
            assert hd.load_robot("ur10").nv == 6
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            hd.load_robot("ur10")  # once per name
    finally:
        ROBOTS.unregister("ur10")
    monkeypatch.setattr(names, "_SHADOWS_CHECKED", set())
    (tmp_path / "ur10.toml").write_text(UR10.format(urdf="ur10_robot.urdf"))
    ROBOTS.register(RobotDeclaration("ur10", tmp_path / "ur10.toml"))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert hd.load_robot("ur10").spec.rated_payload_kg == 10.0
    finally:
        ROBOTS.unregister("ur10")
