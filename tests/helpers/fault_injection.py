"""Kill-and-resume machinery: kill `generate` and `train` mid-run, resume, compare the bytes.

The test is tests/system/test_fault_injection.py; this module holds what it runs, and what the
killed commands import (``generate_cli`` runs in the child process, which finds it as
``helpers.fault_injection``).

For every case: an uninterrupted reference run of the command, then the same command killed
with a signal while work is under way, then the same command again (the resume). A case passes
when

  killed mid-run   the signal arrived before the run finished (no manifest / model yet);
  resumed          the rerun exited 0 and kept the killed run's work: generate keeps every
                   instance the killed run finished (same inode and mtime), train's first new
                   checkpoint is the epoch after the killed run's last one;
  bytes identical  the finished folder equals the reference byte for byte: every instance .h5,
                   its record, generator.json and the manifest (generate); config.json,
                   model.safetensors and any analytic cache (train; timing.json holds only the
                   wall-clock training time, docs/models.md, and is left out);
  orphans 0        no process the killed run started is alive a grace period after its main
                   process ended: its session, its process group, and every descendant seen
                   just before the signal (found by ppid in /proc);
  temporaries 0    no `*.partial*` file is left in or beside the output after the resume.

The matrix: generate with 1 and 2 workers, and train with one preset of every family (an MLP seed
net, a conv net, an LSTM, a residual net on physics, DeLaN, tau-mlp-wide with dropout; train has
no workers option: 1), each under SIGKILL, SIGINT and SIGTERM. The signal goes to the command's
main process only (kill PID, a scheduler's stop): the command itself must stop its workers.
Each command runs in its own session, so the orphan count sees exactly its processes, and with
SIGINT at its default action (a test runner started in the background ignores SIGINT, and an
ignored signal stays ignored across exec: the command would never see the Ctrl-C).

The commands are the real CLI (`python -m hybrid_dyn.cli ...`). `generate` runs through
`generate_cli` below, which only shrinks the quick profile to GENERATOR_SIZES so each run takes
seconds; train uses one tiny dataset made once (the 1-worker generate reference).
"""
from __future__ import annotations

import filecmp
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
TESTS_DIR = Path(__file__).resolve().parents[1]  # on the child's path: it imports helpers.fault_injection

SIGNALS = ("SIGKILL", "SIGINT", "SIGTERM")
# One preset per family (hybrid-dyn presets).
TRAIN_PRESETS = {
    "seed-tip-1": "MLP (seed)",
    "seed-tip-5": "conv (seed)",
    "seed-tip-7": "LSTM (seed)",
    "residual-rnea": "residual on RNEA",
    "delan": "DeLaN",
    "tau-mlp-wide": "MLP with dropout",
}

# The quick profile shrunk to six instances of about a second of simulation work each: long enough
# that a worker is mid-instance when the first instance's record appears (the kill point).
GENERATOR_SIZES = dict(n_instances=6, trajectories=(4, 6), standstill=0.2, speed_scale=(0.5, 0.6),
                       pulse_gap=(0.5, 1.0), pulse_sigma=(0.2, 0.4))
# Tiny training: a few short epochs, so the kill at the first checkpoint leaves most of the run to resume.
TRAIN_ARGS = ["--max-epochs", "6", "--patience", "100", "--batch-size", "64", "--max-batches-per-epoch", "8",
              "--threads", "1", "--device", "cpu", "--quiet"]
TIMING_FILES = {"timing.json"}  # wall-clock figures only (docs/models.md, "Which bytes are reproducible")

GRACE_S = 3.0  # how long a killed run's workers may take to notice and exit
EXIT_WAIT_S = 30.0  # how long the main process may take to unwind after SIGINT / SIGTERM
POLL_S = 0.005
RUN_TIMEOUT_S = 300.0  # a run that takes longer hangs (a reference takes 10-20 s on 2 busy cores)


def generate_cli(argv: list[str]) -> int:
    """`hybrid-dyn generate` with the quick profile shrunk to GENERATOR_SIZES (run in the child process)."""
    import hybrid_dyn.sim.scenarios as scenarios
    from hybrid_dyn.sim.generator_config import PulseConfig
    from hybrid_dyn.cli import main

    sizes = dict(GENERATOR_SIZES)
    pulses = PulseConfig(gap=sizes.pop("pulse_gap"), sigma=sizes.pop("pulse_sigma"))
    full_size = scenarios.scenario_config

    def tiny(name, size="quick", seed=0, **overrides):
        return full_size(name, size, seed=seed, **{**sizes, "pulses": pulses, **overrides})

    scenarios.scenario_config = tiny  # sim/cli.py looks it up when the command runs
    return main(argv)


def generate_argv(out: Path, workers: int) -> list[str]:
    code = f"import sys; sys.path.insert(0, {str(TESTS_DIR)!r}); from helpers import fault_injection as f; " \
           "sys.exit(f.generate_cli(sys.argv[1:]))"
    return [sys.executable, "-c", code, "generate", "--scenario", "paper-ext", "--size", "quick",
            "--out", str(out), "--workers", str(workers), "--quiet"]


def train_argv(data: Path, preset: str, out: Path) -> list[str]:
    return [sys.executable, "-m", "hybrid_dyn.cli", "train", "--data", str(data), "--preset", preset,
            "--out", str(out)] + TRAIN_ARGS


# ------------------------------------------------------------------ processes
def process_table() -> dict[int, dict]:
    """pid -> ppid, process group, session, state, start time (clock ticks), from /proc."""
    table = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                rest = f.read().rsplit(")", 1)[1].split()  # the command name may hold spaces and ')'
        except OSError:
            continue  # ended while we looked
        table[int(entry)] = dict(state=rest[0], ppid=int(rest[1]), pgrp=int(rest[2]), session=int(rest[3]),
                                 start=int(rest[19]))
    return table


def descendants(pid: int, table: dict[int, dict]) -> dict[int, int]:
    """Every process below ``pid`` in the tree: pid -> start time (a reused pid has another start time)."""
    children: dict[int, list[int]] = {}
    for p, info in table.items():
        children.setdefault(info["ppid"], []).append(p)
    found, stack = {}, list(children.get(pid, []))
    while stack:
        p = stack.pop()
        found[p] = table[p]["start"]
        stack.extend(children.get(p, []))
    return found


def survivors(leader: int, seen: dict[int, int]) -> list[dict]:
    """Live processes of a killed run: its session or group (the leader's pid), or seen below it before the kill."""
    out = []
    for p, info in process_table().items():
        if info["state"] in ("Z", "X"):
            continue  # dead, waiting to be reaped
        ours = info["session"] == leader or info["pgrp"] == leader or seen.get(p) == info["start"]
        if ours:
            try:
                cmd = Path(f"/proc/{p}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                cmd = "?"
            out.append({"pid": p, "start": info["start"], "cmdline": cmd.strip()[:160]})
    return out


def end_processes(procs: list[dict]) -> None:
    """SIGKILL processes this test started (checked by start time), and wait until they are gone."""
    for pr in procs:
        info = process_table().get(pr["pid"])
        if info is not None and info["start"] == pr["start"]:
            try:
                os.kill(pr["pid"], signal.SIGKILL)
            except ProcessLookupError:
                pass
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(
            process_table().get(pr["pid"], {}).get("start") == pr["start"]
            and process_table()[pr["pid"]]["state"] not in ("Z", "X") for pr in procs):
        time.sleep(0.05)


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def launch(argv: list[str], log: Path) -> subprocess.Popen:
    """Start a command in its own session (its own process group), output to ``log``, no stdin, SIGINT at
    its default action whatever the test runner's is."""
    with open(log, "ab") as f:
        return subprocess.Popen(argv, cwd=REPO, stdin=subprocess.DEVNULL, stdout=f, stderr=subprocess.STDOUT,
                                start_new_session=True, preexec_fn=_default_sigint)


def log_tail(log: Path, n: int = 1500) -> str:
    return log.read_text(errors="replace")[-n:] if log.exists() else ""


def run_to_end(argv: list[str], log: Path, watch=None) -> tuple[int, float]:
    """Run a command to its end (``watch()`` is called every poll); (exit status, wall seconds)."""
    t0 = time.perf_counter()
    proc = launch(argv, log)
    while proc.poll() is None:
        if watch is not None:
            watch()
        if time.perf_counter() - t0 > RUN_TIMEOUT_S:
            os.killpg(proc.pid, signal.SIGKILL)
        time.sleep(POLL_S)
    if watch is not None:
        watch()
    return proc.returncode, time.perf_counter() - t0


def run_and_kill(argv: list[str], log: Path, ready, sig: str) -> dict:
    """Run a command, send ``sig`` to its main process as soon as ``ready()``, and count what outlives it."""
    t0 = time.perf_counter()
    proc = launch(argv, log)
    seen: dict[int, int] = {}
    sent = False
    while proc.poll() is None and time.perf_counter() - t0 < RUN_TIMEOUT_S:
        if ready():
            seen = descendants(proc.pid, process_table())  # the workers, just before the signal
            os.kill(proc.pid, getattr(signal, sig))
            sent = True
            break
        time.sleep(POLL_S)
    main_exited = True
    try:
        proc.wait(timeout=EXIT_WAIT_S)
    except subprocess.TimeoutExpired:
        main_exited = False  # it hangs: counted below as a survivor, then ended
    time.sleep(GRACE_S)
    alive = survivors(proc.pid, seen)
    end_processes(alive)  # so that nothing of the killed run races the resume
    if not main_exited:
        proc.wait()
    return {"signal_sent": sent, "exit_status": proc.returncode, "main_exited": main_exited,
            "seconds_to_kill": round(time.perf_counter() - t0 - GRACE_S, 2),
            "processes_at_kill": len(seen), "orphans": alive}


# ------------------------------------------------------------------ files
def compare_folders(a: Path, b: Path, skip=frozenset()) -> dict:
    """Byte-for-byte comparison of two folders' files (relative names), ``skip``: file names left out."""
    def files(root):
        return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and p.name not in skip}

    fa, fb = files(a), files(b)
    differ = sorted(n for n in fa & fb if not filecmp.cmp(a / n, b / n, shallow=False))
    return {"identical": fa == fb and not differ, "compared": len(fa & fb), "differ": differ,
            "only_in_reference": sorted(fa - fb), "only_in_resumed": sorted(fb - fa)}


def temporaries(out: Path) -> list[str]:
    """``*.partial*`` files in ``out`` or beside it (``unique_temp`` names: NAME.partial.<pid>.<random>)."""
    inside = [str(p.relative_to(out.parent)) for p in out.rglob("*") if ".partial" in p.name] if out.exists() else []
    beside = [p.name for p in out.parent.glob(f"{out.name}.partial*")]
    return sorted(inside + beside)


def stat_key(p: Path) -> tuple[int, int]:
    st = p.stat()
    return st.st_ino, st.st_mtime_ns


def finished_instances(out: Path) -> dict[str, tuple]:
    """Instances with a completion record and their file: name -> (inode, mtime) of both."""
    found = {}
    for rec in sorted((out / "instances").glob("inst_*.json")):
        h5 = rec.with_suffix(".h5")
        if h5.is_file():
            found[rec.stem] = (stat_key(rec), stat_key(h5))
    return found


def checkpoint_epoch(out: Path):
    try:
        return json.loads((out / "checkpoint.json").read_text())["epoch"]
    except (OSError, ValueError, KeyError):
        return None


# ------------------------------------------------------------------ cases
@dataclass
class Case:
    command: str  # "generate" or "train"
    signal: str
    workers: int
    preset: str | None = None
    result: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        return "generate" if self.command == "generate" else f"train {self.preset}"

    @property
    def key(self) -> str:
        return f"{self.command}-{self.preset or 'w%d' % self.workers}-{self.signal}"

    def reference_key(self) -> str:
        return f"{self.command}-{self.preset or 'w%d' % self.workers}"


def matrix() -> list[Case]:
    """Every case: generate with 1 and 2 workers and train with each of TRAIN_PRESETS, under each signal."""
    cases = [Case("generate", s, w) for w in (1, 2) for s in SIGNALS]
    return cases + [Case("train", s, 1, p) for p in TRAIN_PRESETS for s in SIGNALS]


def case_argv(case: Case, out: Path, data: Path) -> list[str]:
    return generate_argv(out, case.workers) if case.command == "generate" else train_argv(data, case.preset, out)


def run_case(case: Case, reference: Path, data: Path, work: Path) -> dict:
    """Kill the case's command mid-run, resume it, and check it against ``reference`` (train reads ``data``)."""
    out, log = work / case.key, work / f"{case.key}.log"
    argv = case_argv(case, out, data)
    t0 = time.perf_counter()
    if case.command == "generate":
        ready = lambda: any((out / "instances").glob("inst_*.json"))  # noqa: E731 (a worker has finished one)
        done_file = out / "manifest.json"
    else:
        ready = lambda: (out / "checkpoint.json").is_file()  # noqa: E731 (epoch 0 is committed)
        done_file = out / "config.json"
    killed = run_and_kill(argv, log, ready, case.signal)
    killed["mid_run"] = killed["signal_sent"] and not done_file.exists()
    killed["temporaries_after_kill"] = temporaries(out)

    # What the killed run left, to tell a resume from a fresh start.
    before = finished_instances(out) if case.command == "generate" else {}
    last_epoch = checkpoint_epoch(out) if case.command == "train" else None
    ck = out / "checkpoint.json"
    ck_key = stat_key(ck) if ck.exists() else None
    first_new_epoch = []

    def watch_checkpoint():
        if not first_new_epoch and ck.exists():
            try:
                changed = stat_key(ck) != ck_key
            except OSError:
                return
            if changed:
                epoch = checkpoint_epoch(out)
                if epoch is not None:
                    first_new_epoch.append(epoch)

    rc, resume_s = run_to_end(argv, log, watch=watch_checkpoint if case.command == "train" else None)
    if case.command == "generate":
        after = finished_instances(out)
        kept = sum(after.get(n) == k for n, k in before.items())
        resumed = rc == 0 and done_file.exists() and len(before) > 0 and kept == len(before)
        evidence = f"{kept}/{len(before)} finished instances kept of {GENERATOR_SIZES['n_instances']}"
    else:
        new = first_new_epoch[0] if first_new_epoch else None
        resumed = rc == 0 and done_file.exists() and last_epoch is not None and new == last_epoch + 1
        evidence = f"killed after epoch {last_epoch}, resume's first checkpoint epoch {new}"
    same = compare_folders(reference, out, skip=TIMING_FILES if case.command == "train" else frozenset())
    temps = temporaries(out)
    ok = killed["mid_run"] and resumed and same["identical"] and not killed["orphans"] and not temps
    res = {"case": case.name, "command": case.command, "signal": case.signal, "workers": case.workers,
           "preset": case.preset, "ok": ok, "killed": killed, "resume_exit_status": rc, "resumed": resumed,
           "resume_evidence": evidence, "bytes": same, "orphans": len(killed["orphans"]), "temporaries": temps,
           "seconds": round(time.perf_counter() - t0, 1), "resume_seconds": round(resume_s, 1)}
    if not ok:
        res["log_tail"] = log_tail(log)
    return res


# ------------------------------------------------------------------ verdicts
def failure_notes(r: dict) -> list[str]:
    """What failed in a case's result (``run_case``), one note per check; empty when it passed."""
    notes = []
    k = r["killed"]
    if not k["mid_run"]:
        notes.append(f"not killed mid-run: the run finished before the signal or in spite of it "
                     f"(signal sent: {k['signal_sent']}, exit status {k['exit_status']})")
    if not k["main_exited"]:
        notes.append(f"the main process did not exit within {EXIT_WAIT_S:g} s of {r['signal']}")
    if not r["resumed"]:
        notes.append(f"not resumed: exit status {r['resume_exit_status']}; {r['resume_evidence']}")
    b = r["bytes"]
    if not b["identical"]:
        notes.append(f"differ: {b['differ']}; only in reference: {b['only_in_reference']}; "
                     f"only in resumed: {b['only_in_resumed']}")
    for o in k["orphans"]:
        notes.append(f"orphan pid {o['pid']}: {o['cmdline']}")
    if r["temporaries"]:
        notes.append(f"temporaries: {r['temporaries']}")
    return notes
