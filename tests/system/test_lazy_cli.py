"""``hybrid-dyn --help``, ``hybrid-dyn import --help`` and ``hybrid-dyn estimate --help`` print a list, not a
trained net: none of them imports PyTorch (each once took 4.5 s and 585 MB, the whole toolkit imported)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from helpers import REPO

pytestmark = pytest.mark.system

PROBE = """
import contextlib, io, json, sys
from hybrid_dyn.cli import main
out = io.StringIO()
with contextlib.redirect_stdout(out):
    try:
        main({argv!r})
    except SystemExit as stop:
        code = stop.code
print(json.dumps({{"code": code, "torch": "torch" in sys.modules, "pinocchio": "pinocchio" in sys.modules,
                  "help": out.getvalue()}}))
"""


def _help(argv: list[str]) -> dict:
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    done = subprocess.run([sys.executable, "-c", PROBE.format(argv=argv)], env=env, capture_output=True, text=True,
                          timeout=120, cwd=REPO)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_importing_the_parser_imports_no_torch():
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    code = "import sys; from hybrid_dyn.cli import build_parser; build_parser(''); print('torch' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.split() == ["False"], done.stdout + done.stderr[-2000:]


@pytest.mark.parametrize("argv, says", [([], "import a robot log"), (["import"], "--spec"),
                                        (["estimate"], "momentum-observer")])
def test_the_help_imports_no_torch(argv, says):
    got = _help([*argv, "--help"])
    assert got["code"] == 0 and says in got["help"], got["help"]
    assert not got["torch"]
    if not argv:  # the list of commands needs no area of the toolkit at all
        assert not got["pinocchio"]


def test_every_command_is_listed_by_the_module_that_builds_it():
    """:data:`COMMANDS` against the modules: each module builds exactly the commands the table gives it."""
    import importlib

    from hybrid_dyn.cli import COMMANDS

    class Record:
        def __init__(self):
            self.names = []

        def add_parser(self, name, **kwargs):
            assert "help" not in kwargs, f"{name}: its help line is COMMANDS'"
            self.names.append(name)
            return __import__("argparse").ArgumentParser(prog=name)

    for module in dict.fromkeys(m for m, _ in COMMANDS.values()):
        record = Record()
        importlib.import_module(module).register(record)
        assert record.names == [n for n, (m, _) in COMMANDS.items() if m == module], module


def test_a_command_runs_with_only_its_module_built(tmp_path, capsys):
    from hybrid_dyn.cli import build_parser, main

    assert main(["robots"]) == 0 and "panda" in capsys.readouterr().out
    args = build_parser("import").parse_args(["import", "--spec", "s.toml", "--out", "d"])
    assert args.spec == "s.toml" and callable(args.func)
    with pytest.raises(SystemExit):
        main(["no-such-command"])
    assert "invalid choice: 'no-such-command'" in capsys.readouterr().err
