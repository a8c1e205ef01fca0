"""A tiny bench profile for imported logs (a few rows of each kind, a few training steps)."""

# A few rows of each kind, to keep the test seconds: analytic (one runs, one needs a base sensor), a tip-force
# net (no tip force in a log), a seed net (trains one tiny epoch) and a row identified on the log itself.
ROWS = ["rnea", "rnea-bw", "torques-pinv", "seed-tip-1", "seed-tau-mlp", "identified-ols"]


def tiny_profile(data, **kw):
    """``profile_for_data(data)`` running only ROWS, one worker, two training steps."""
    from hybrid_dyn.bench.profiles import profile_for_data

    return profile_for_data(data, families=(), rows=tuple(ROWS), workers=1,
                            train=dict(budget_steps=2, budget_evals=1, batch_size=64, progress=False), **kw)


def written_report(folder, rows, profile=None):
    """A report folder as the bench leaves it, without running one: results.csv of ``rows`` (dicts) and a
    run.json with the bench's marker, ``profile`` and the digest of both (no predictions.h5: ``report`` and
    ``compare`` then check every row against the digest alone)."""
    import json
    from pathlib import Path

    from hybrid_dyn.bench.integrity import DIGEST_KEY, results_digest
    from hybrid_dyn.bench.results import write_results

    folder = Path(folder)
    folder.mkdir(parents=True)
    write_results(folder / "results.csv", rows)
    meta = {"bench_report": 1, "profile": {"scenario_overrides": {}} if profile is None else profile}
    meta[DIGEST_KEY] = results_digest(folder / "results.csv", meta)
    (folder / "run.json").write_text(json.dumps(meta))
    return folder


def killed_bench(data, out, rows, kill_at: str, data_root, work_root) -> int:
    """Run the tiny bench on ``data`` with ``rows`` in a child process that SIGKILLs itself (kill -9: no
    handler, no finally runs) as soon as the bench logs a message containing ``kill_at``; the child's exit
    status (-9 when it was killed there)."""
    import subprocess
    import sys

    from helpers import REPO

    code = ("import dataclasses, os, signal, sys\n"
            f"sys.path.insert(0, {str(REPO / 'tests')!r})\n"
            "from helpers.bench import tiny_profile\n"
            "from hybrid_dyn.bench.runner import run_bench\n"
            f"profile = dataclasses.replace(tiny_profile([{str(data)!r}]), rows={tuple(rows)!r})\n"
            "def log(message):\n"
            f"    if {kill_at!r} in message:\n"
            "        os.kill(os.getpid(), signal.SIGKILL)\n"
            f"run_bench(profile, {str(out)!r}, data_root={str(data_root)!r}, work_root={str(work_root)!r}, log=log)\n")
    return subprocess.run([sys.executable, "-c", code], stdin=subprocess.DEVNULL, capture_output=True,
                          timeout=300).returncode


def edit_results(folder, model, /, **cells):
    """Edit by hand the cells of ``model``'s rows in ``folder``/results.csv (as a user with a text editor);
    positional-only, so that ``cells`` may hold any column, ``model`` too."""
    import csv
    from pathlib import Path

    path = Path(folder) / "results.csv"
    rows = list(csv.DictReader(path.open()))
    for r in rows:
        if r["model"] == model:
            r.update(cells)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
