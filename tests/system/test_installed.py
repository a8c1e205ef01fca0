"""An installed toolkit works outside the checkout: the robot descriptions and the
real-log import specs ship in the wheel as package data, and are found there, not through the checkout.

The wheel is built from a copy of the checkout's sources (pip builds in-tree otherwise, leaving build/
and egg-info behind), installed into a folder of its own, and imported from an empty folder with only
that folder on the path: the checkout is neither on sys.path nor the working directory.
"""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import REPO

pytestmark = pytest.mark.system

# Run in the installed toolkit: where hybrid_dyn came from, the Panda's joint count and tool frame,
# the real-panda spec's robot and split, and the robot names the installed descriptions give.
PROBE = """
import json, hybrid_dyn as hd
from hybrid_dyn.data.logs.importer import read_spec
from hybrid_dyn.data.logs.real_logs import REAL_SETS, missing_real_log, real_spec_path
from hybrid_dyn.description import ROBOTS, load_spec
robot = hd.load_robot("panda")
spec = read_spec(real_spec_path("real-panda"))
official = hd.load_robot("panda", params="franka_official")
mass = lambda r: sum(i.mass for i in r.model.inertias)  # kg, every body of the model
print(json.dumps({"file": hd.__file__, "nv": robot.nv, "tool_frame": load_spec("panda").tool_frame,
                  "robots": list(ROBOTS.names(data_only=False)),
                  "data_only": list(ROBOTS.names(data_only=True)),
                  "spec_robot": spec.robot, "spec_split": spec.split_by,
                  "specs": sorted(n for n in REAL_SETS if real_spec_path(n).is_file()),
                  "logs_missing": {n: missing_real_log(n) is not None for n in REAL_SETS},
                  "params_differ": float(abs(mass(official) - mass(robot)))}))
"""


def _copy_sources(dst: Path) -> Path:
    """The files a wheel is built from, without build outputs or caches."""
    dst.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, dst / name)
    shutil.copytree(REPO / "src", dst / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "*.pyc"))
    return dst


@pytest.mark.slow
def test_installed_wheel_loads_the_panda_and_the_real_specs_outside_the_checkout(tmp_path):
    src = _copy_sources(tmp_path / "src-copy")
    wheels, site, elsewhere = tmp_path / "wheels", tmp_path / "site", tmp_path / "elsewhere"
    elsewhere.mkdir()
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run(pip + ["wheel", "--no-deps", "--no-build-isolation", "-w", str(wheels), str(src)],
                   check=True, cwd=tmp_path, capture_output=True)
    wheel = next(wheels.glob("hybrid_dyn-*.whl"))
    subprocess.run(pip + ["install", "--no-deps", "--target", str(site), str(wheel)],
                   check=True, cwd=tmp_path, capture_output=True)
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "HYBRID_DYN_ROBOTS", "HYBRID_DYN_REAL_SPECS", "HYBRID_DYN_REAL_LOGS")}
    env["PYTHONPATH"] = str(site)
    run = subprocess.run([sys.executable, "-c", PROBE], cwd=elsewhere, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads(run.stdout.strip().splitlines()[-1])
    assert Path(got["file"]).resolve().is_relative_to(site.resolve())  # the wheel's copy, not the checkout's
    assert got["nv"] == 7 and got["tool_frame"] == "panda_hand_tcp"
    assert {"panda", "ur5", "xarm7", "kuka-lwr", "baxter"} <= set(got["robots"]) and "sarcos" in got["data_only"]
    assert got["params_differ"] > 0  # the parameter-set JSONs shipped too: franka_official is another mass
    assert got["spec_robot"] == "panda[tool=none]" and got["spec_split"] == "time"
    assert got["specs"] == sorted(["real-kuka", "real-baxter", "real-sarcos", "real-panda"])
    # The three public logs ship beside their specs; the Panda's (GPL-3.0) does not, and says so.
    assert got["logs_missing"] == {"real-kuka": False, "real-baxter": False, "real-sarcos": False, "real-panda": True}
    # The installed command imports a shipped log by its set name (the spec and the .mat inside the package).
    run = subprocess.run([sys.executable, "-m", "hybrid_dyn.cli", "import", "--spec", "real-sarcos", "--out", "sarcos",
                          "--json"], cwd=elsewhere, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads(run.stdout[run.stdout.index("{"):])
    assert summary["rows_kept"] == 4449 and (elsewhere / "sarcos" / "manifest.json").is_file()
