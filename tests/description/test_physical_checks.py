"""Input checks of robot descriptions before any output exists: URDF structure, parameter files
(split settings: data/test_split_checks.py; the bench's arguments: bench/test_bench_refusals.py).

Each case is one the issue found breaking: a hang, a traceback or a silently wrong dataset. The
expected answer is a one-line HybridDynError naming the problem, and nothing written.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.description import RobotDescriptionError, read_param_file, resolve_robot, robots_dir
from hybrid_dyn.description.physical_checks import inertial_problems, urdf_tree_problems

from helpers.timelimit import time_limit

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
    from hybrid_dyn.data.logs.importer import LogSpec

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
