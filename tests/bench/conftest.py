"""Fixtures of the bench tests: one tiny bench on an imported log, shared by the bench and report tests."""
import pytest

from hybrid_dyn.cli import main as cli_main

from helpers.bench import tiny_profile
from helpers.logs import write_log


@pytest.fixture(scope="package")
def bench(tmp_path_factory):
    """A tiny imported log, and the bench on it (Python API: run_bench(profile_for_data(...)))."""
    from hybrid_dyn.bench.runner import run_bench

    tmp = tmp_path_factory.mktemp("bench-data")
    spec = write_log(tmp / "logs")
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp / "my-log")]) == 0
    messages = []
    rows = run_bench(tiny_profile([tmp / "my-log"]), tmp / "report", data_root=tmp / "data",
                     work_root=tmp / "runs", log=messages.append)
    return tmp, rows, messages
