"""A third-party plugin (plugins.py): an installed distribution with a ``hybrid_dyn.plugins`` entry point adds
a tip-force method, a family, a bench row and a robot through the public registries, with no edit of the toolkit.

The plugin is installed for real: a package of its own (``pyproject.toml`` with the entry point, its module and
its robot's TOML as package data), built and installed by pip into a folder on the path of a fresh interpreter.
In that interpreter ``load_robot`` finds the plugin's robot by its name before anything loaded plugins (a
registry's miss loads them), the estimator runs the plugin's method, the bench's help lists the method's rows
and the plugin's row and family, the bench runs both into its report on a tiny dataset, and the control-loop
example takes the plugin's method.
"""
import csv
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.system

SRC = Path(__file__).resolve().parents[2] / "src"

PLUGIN = '''
"""A toy hybrid_dyn plugin: a method (the base momentum observer at half its gain), a family, a row, a robot."""
from pathlib import Path

import numpy as np

from hybrid_dyn.analytic.method_declaration import TIP_FORCE_METHODS, Method
from hybrid_dyn.analytic.observer_methods import BaseMomentumMethod
from hybrid_dyn.bench.families import FAMILIES, Family
from hybrid_dyn.bench.rows import ROWS, Predictor, Row
from hybrid_dyn.description.robots import ROBOTS, RobotDeclaration


class HalfGain(BaseMomentumMethod):
    def choose(self, noise):
        return 0.5 * super().choose(noise)


TIP_FORCE_METHODS.register(Method("toy-half-momentum", "the base momentum observer at half its gain (a plugin's)",
                                  ("base_wrench",), False, False, True, "momentum_gain", HalfGain))
FAMILIES.register(Family("toy-baseline", "a plugin's baselines", fitted=True))


def build(ds, ctx):
    mean = np.concatenate([i["tau_m"] for i in ds.split("train")]).mean(axis=0)
    return Predictor(predict=lambda insts: [np.tile(mean, (len(i), 1)) for i in insts],
                     single_call=lambda inst, k: mean, inputs="nothing")


ROWS.register(Row("toy-tau-mean", "joint_torque", "toy-baseline", needs=("q", "tau_m"), needs_urdf=False,
                  build=build))
ROBOTS.register(RobotDeclaration("toy-ur5", Path(__file__).with_name("toy-ur5.toml")))
'''

PYPROJECT = '''
[build-system]
requires = ["setuptools"]
build-backend = "setuptools.build_meta"

[project]
name = "hd-toy-plugin"
version = "0.1"

[project.entry-points."hybrid_dyn.plugins"]
toy = "hd_toy_plugin"

[tool.setuptools]
packages = ["hd_toy_plugin"]

[tool.setuptools.package-data]
hd_toy_plugin = ["*.toml"]
'''

# What the fresh interpreter runs: load_robot first (nothing has loaded the plugin yet), then the estimator and
# the CLI.
SCRIPT = '''
import contextlib, io, json, sys
import numpy as np
from hybrid_dyn import TipForceEstimator, load_robot
from hybrid_dyn.data import load_dataset
from hybrid_dyn.plugins import LOADED

data, out = sys.argv[1], sys.argv[2]
assert not LOADED, LOADED  # importing the toolkit loads no plugin
toy_robot = load_robot("toy-ur5")
first = dict(LOADED)
run = load_dataset(data).split("test")[0]
rate = 100.0
est = TipForceEstimator.analytic(load_robot("panda"), "toy-half-momentum", call_hz=rate, encoder_resolution=0.0)
base = TipForceEstimator.analytic(load_robot("panda"), "base-momentum", call_hz=rate, encoder_resolution=0.0)
for e in (est, base):
    for k in range(len(run)):
        e.estimate_tip_force(run.q[k], run.qd[k], base_wrench=run.base_wrench[k], t=k / rate)
from hybrid_dyn.cli import main
helps = {}
for command in ("bench", "study"):
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        try:
            main([command, "--help"])
        except SystemExit:
            pass
    helps[command] = "".join(text.getvalue().split())  # argparse wraps at hyphens
code = main(["bench", "--data", data, "--rows", "toy-half-momentum,toy-tau-mean", "--out", out, "--workers", "1"])
print(json.dumps({"loaded": first, "method": est.method, "gain": float(est.bandwidth),
                  "robot": [toy_robot.name, toy_robot.nv],
                  "base_gain": float(base.bandwidth), "help": helps, "code": code}))
'''


def _install(site: Path, tmp: Path) -> None:
    """The plugin as a user makes it: a package with its pyproject.toml, built and installed by pip (no index:
    setuptools is the toolkit's environment's) into ``site``."""
    from hybrid_dyn.description.robots import shipped

    package = tmp / "hd-toy-plugin"
    (package / "hd_toy_plugin").mkdir(parents=True)
    (package / "pyproject.toml").write_text(PYPROJECT)
    (package / "hd_toy_plugin" / "__init__.py").write_text(textwrap.dedent(PLUGIN))
    # The plugin's robot: the UR5's description under another name (its URDF from example-robot-data).
    toml = (shipped() / "ur5.toml").read_text()
    (package / "hd_toy_plugin" / "toy-ur5.toml").write_text(toml.replace('name = "ur5"', 'name = "toy-ur5"', 1))
    subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", "install", "--no-deps",
                    "--no-build-isolation", "--no-index", "--target", str(site), str(package)],
                   check=True, cwd=tmp, capture_output=True, timeout=300)
    assert (site / "hd_toy_plugin" / "toy-ur5.toml").is_file()
    assert next(site.glob("hd_toy_plugin-0.1.dist-info/entry_points.txt")).read_text().count("hd_toy_plugin") == 1


def test_an_installed_plugin_adds_a_method_and_a_row_to_the_estimator_the_help_and_the_report(tmp_path, panda):
    from hybrid_dyn.data.synthetic import make_synthetic_dataset

    data = make_synthetic_dataset(tmp_path / "d", panda, n_instances=4, n_samples=300, seed=3, noise=0.01,
                                  contact_free_s=0.6)
    site = tmp_path / "site"
    site.mkdir()
    _install(site, tmp_path)
    out = tmp_path / "report"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(SRC)])}
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(data), str(out)], env=env, capture_output=True,
                          text=True, timeout=600, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])

    assert got["loaded"] == {"toy": "hd_toy_plugin"}  # imported once, by load_robot's lookup of its robot
    assert got["method"] == "toy-half-momentum"
    assert got["robot"] == ["toy-ur5", 6]  # declared by the plugin, loaded by name
    assert got["gain"] == pytest.approx(0.5 * got["base_gain"])  # the plugin's rule, run by the estimator
    bench_help = got["help"]["bench"]
    for name in ("toy-half-momentum", "toy-half-momentum-val", "toy-tau-mean", "toy-baseline"):
        assert name in bench_help, name
    assert got["code"] == 0
    with open(out / "results.csv", newline="") as f:
        results = {r["model"]: r for r in csv.DictReader(f)}
    assert {name: (r["family"], r["status"]) for name, r in results.items()} == {
        "toy-half-momentum": ("analytic", "ok"), "toy-tau-mean": ("toy-baseline", "ok")}
    assert "toy-tau-mean" in (out / "joint_torque.md").read_text()
    assert "toy-half-momentum" in (out / "tip_force.md").read_text()
    # The example's --method choices are the registry's, plugins included (a fresh interpreter again).
    example = subprocess.run([sys.executable, str(SRC.parent / "examples" / "control_loop.py"), "--method",
                              "toy-half-momentum", "--seconds", "4"], env=env, capture_output=True, text=True,
                             timeout=600, cwd=tmp_path)
    assert example.returncode == 0, example.stderr[-3000:]
    assert "estimator: toy-half-momentum;" in example.stdout


def test_a_plugin_that_fails_to_import_is_named_and_left_out(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    (site / "hd_broken.py").write_text("raise ImportError('needs a package that is not installed')\n")
    info = site / "hd_broken-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hd-broken\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[hybrid_dyn.plugins]\nbroken = hd_broken\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(SRC)])}
    done = subprocess.run([sys.executable, "-m", "hybrid_dyn.cli", "bench", "--help"], env=env, capture_output=True,
                          text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0 and "--rows" in done.stdout
    assert "plugin 'broken' (hd_broken) failed to load: ImportError: needs a package" in done.stderr
