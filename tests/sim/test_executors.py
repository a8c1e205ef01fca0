"""Generation's executors: Ray gives the local files byte for byte, the executor choice
is checked, and a killed `generate` leaves no worker alive."""
import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hybrid_dyn.data import load_dataset
from hybrid_dyn.sim.executors import ProcessExecutor, RayExecutor, make_executor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.scenarios import scenario_config

from helpers.files import dir_bytes


@pytest.mark.slow
def test_ray_generation_equals_local(tmp_path):
    """A `quick` generation as Ray tasks on a local 2-CPU Ray instance: the same files, byte for byte."""
    cfg = scenario_config("paper-ext", "quick", seed=0)
    local = generate_dataset(cfg, tmp_path / "local", executor=ProcessExecutor(2), progress=False)
    ray_ex = RayExecutor(workers=2)
    on_ray = generate_dataset(cfg, tmp_path / "ray", executor=ray_ex, progress=False)
    assert ray_ex.workers == 2  # the cluster Ray reported: this ran on Ray, with 2 CPUs
    a, b = dir_bytes(local), dir_bytes(on_ray)
    assert sorted(a) == sorted(b) and len([k for k in a if k.endswith(".h5")]) == cfg.n_instances
    assert a == b
    assert load_dataset(on_ray).checksum == load_dataset(local).checksum


def test_executor_choice_errors():
    with pytest.raises(ValueError, match="--ray-address needs --executor ray"):
        make_executor(1, "local", address="auto")
    with pytest.raises(ValueError, match="executor must be one of"):
        make_executor(1, "dask")
    assert isinstance(make_executor(2, "ray"), RayExecutor)


# -------------------------------------------------------- worker processes
def _session_processes(sid: int) -> dict:
    """pid -> command line of the live (not zombie) processes of session ``sid``, its leader excluded.

    The command runs as a session leader, so its workers and the multiprocessing resource
    tracker stay in its session even after they are re-parented to init.
    """
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == sid:
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
            cmd = Path(f"/proc/{entry}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue  # exited meanwhile
        state, _ppid, _pgrp, session = stat.rsplit(")", 1)[1].split()[:4]
        if int(session) == sid and state != "Z":
            found[int(entry)] = cmd
    return found


def _ignores_sigint(pid: int) -> bool:
    """The worker initializer ignores SIGINT as its last step: set means parent-death handling is in place."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigIgn:"):
            return bool(int(line.split()[1], 16) & (1 << (signal.SIGINT - 1)))
    return False


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_generate_workers_die_with_their_parent(tmp_path, sig):
    """`generate --workers 2` killed while its workers run: no worker and no resource tracker survive it.

    SIGKILL runs no cleanup in the parent (the workers end by the parent-death signal);
    SIGTERM unwinds like Ctrl-C (exit 143) and stops the workers.
    """
    cmd = [sys.executable, "-m", "hybrid_dyn.cli", "generate", "--size", "quick", "--workers", "2",
           "--out", str(tmp_path / "ds"), "--quiet"]
    # SIGINT at its default, whatever the test runner's is: the workers' SigIgn is the readiness signal.
    with open(tmp_path / "stderr.txt", "wb") as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, start_new_session=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        # Workers running: both alive and one instance finished (4 or more of the 6 are still to do).
        deadline = time.monotonic() + 180
        while True:
            workers = [p for p, c in _session_processes(proc.pid).items() if "spawn_main" in c]
            if len(workers) == 2 and list((tmp_path / "ds" / "instances").glob("*.json")):
                break
            assert proc.poll() is None, (tmp_path / "stderr.txt").read_text()
            assert time.monotonic() < deadline, "no instance was finished within 180 s"
            time.sleep(0.2)
        # And past their initializer (its last step ignores SIGINT); code without one is killed after 10 s.
        deadline = time.monotonic() + 10
        while not all(_ignores_sigint(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        proc.send_signal(sig)
        rc = proc.wait(timeout=60)
        deadline = time.monotonic() + 10
        while _session_processes(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        left = _session_processes(proc.pid)
        assert not left, f"still alive after {signal.Signals(sig).name} of the parent: {left}"
        if sig == signal.SIGTERM:
            assert rc == 143, (tmp_path / "stderr.txt").read_text()
            assert "interrupted" in (tmp_path / "stderr.txt").read_text()
    finally:
        for pid in [proc.pid, *_session_processes(proc.pid)]:  # only what this test started
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        proc.wait()
