"""The CLI tells a user's mistake (one line, exit 2) from a bug in the toolkit (its traceback, exit 1)."""
import subprocess
import sys

import pytest

from hybrid_dyn.cli import main
from hybrid_dyn.errors import HybridDynError, UsageError

pytestmark = pytest.mark.system


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, panda):
    from hybrid_dyn.data.synthetic import make_synthetic_dataset

    return make_synthetic_dataset(tmp_path_factory.mktemp("cli") / "d", panda, n_instances=3, n_samples=20)


@pytest.mark.parametrize("argv, says", [
    (["bench", "--profile", "nope"], "unknown bench profile 'nope'"),
    (["train", "--data", "{tiny}", "--preset", "nope", "--out", "{tmp}/m"], "unknown preset 'nope'"),
    (["train", "--data", "{tmp}/missing", "--preset", "seed-tip-11", "--out", "{tmp}/m"], "not a directory"),
    (["tune", "--data", "{tiny}", "--preset", "seed-tip-11", "--trials", "1", "--storage", "redis://h/0",
      "--out", "{tmp}/t"], "storage must be an RDB URL"),
    (["tune", "--data", "{tiny}", "--preset", "seed-tip-11", "--trials", "0", "--out", "{tmp}/t"],
     "need n_trials >= 1"),
    (["import", "--spec", "{tmp}/missing.toml", "--out", "{tmp}/i"], "missing.toml does not exist"),
    (["identify", "--data", "{tiny}", "--splits", "train,nope", "--out", "{tmp}/p.json"], "split must be one of"),
], ids=["profile", "preset", "no-dataset", "storage", "trials", "spec", "split"])
def test_a_user_error_is_one_line_and_exit_2(argv, says, tiny, tmp_path, capsys):
    argv = [a.format(tiny=tiny, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and says in err and err.count("\n") == 1, err
    assert "Traceback" not in err


def test_user_input_errors_are_the_toolkits_own(tmp_path):
    """The library paths the CLI calls raise HybridDynError subclasses for bad input, not bare ValueError."""
    from hybrid_dyn.bench.profiles import PROFILES
    from hybrid_dyn.data.derivatives import DerivativeFilter
    from hybrid_dyn.data.store import fetch_dataset
    from hybrid_dyn.learn.presets import PRESETS
    from hybrid_dyn.sim.executors import ProcessExecutor, make_executor
    from hybrid_dyn.sim.scenarios import scenario_config

    for call in (lambda: PROFILES.lookup("nope"), lambda: PRESETS.lookup("nope"), lambda: make_executor(1, "dask"),
                 lambda: make_executor(1, "local", address="auto"), lambda: ProcessExecutor(0),
                 lambda: DerivativeFilter(method="spline"), lambda: DerivativeFilter(window_s=-1.0),
                 lambda: fetch_dataset(str(tmp_path), tmp_path / "copy"), lambda: scenario_config("nope")):
        with pytest.raises(HybridDynError):
            call()
    with pytest.raises(UsageError, match="executor must be one of"):  # and still a ValueError for old callers
        make_executor(1, "dask")
    assert issubclass(UsageError, ValueError)


def test_an_internal_bug_is_not_reported_as_a_user_error(monkeypatch, capsys):
    """A ValueError from the toolkit's own code is a bug: it propagates (traceback, exit 1), it is not exit 2."""
    import hybrid_dyn.bench.cli as bench_cli

    def buggy(args):
        raise ValueError("injected internal bug")

    monkeypatch.setattr(bench_cli, "cmd_bench", buggy)
    with pytest.raises(ValueError, match="injected internal bug"):
        main(["bench", "--profile", "quick"])
    assert "error:" not in capsys.readouterr().err


@pytest.mark.slow
def test_an_internal_bug_shows_its_traceback_from_the_command_line():
    code = ("import sys, hybrid_dyn.bench.cli as c\n"
            "def buggy(args): raise ValueError('injected internal bug')\n"
            "c.cmd_bench = buggy\n"
            "from hybrid_dyn.cli import main\n"
            "sys.exit(main(['bench', '--profile', 'quick']))\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 1, run.stderr
    assert "Traceback (most recent call last)" in run.stderr and "ValueError: injected internal bug" in run.stderr
    assert "error: injected" not in run.stderr
