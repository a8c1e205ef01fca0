"""Output paths: the toolkit replaces only what it can prove it wrote.

Two tools every command that writes a folder or file uses:

- ``output_lock(path)``: an exclusive, non-blocking ``fcntl.flock`` on a hidden lock file
  beside ``path`` (``.<name>.lock`` in its parent). A second run on the same output is refused
  at once with ``OutputPathError``; the OS releases the lock when the process dies, so a
  killed run never leaves a stale lock. (flock is local to one machine, or to a file system
  that forwards it; a shared folder under Ray should be a store with per-run temporaries.)
- ``unique_temp(path)``: a temporary name unique to this process and call, beside ``path``,
  so two runs never write the same temporary and a rename is atomic.

What counts as "written by the toolkit" is decided by each writer from its own manifest or
marker, read the same way by every command (``json_marker``): a dataset's manifest.json
(``format``), a generated dataset's generator.json (``config_hash``), a model's config.json and
timing.json (``format``), a report's run.json (``bench_report``), a study summary's JSON (``study``).
A file of that name without the marker is a user's: ``refuse_foreign`` is the common refusal. A
markdown file a command writes on its own (``compare --out``) carries its marker in its first line, an
HTML comment with the sha256 of the rest (``write_own_text``): a file edited since is the user's.
"""
from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import uuid
from pathlib import Path

from .errors import OutputPathError


def lock_path(path) -> Path:
    path = Path(path)
    return path.parent / f".{path.name}.lock"


@contextlib.contextmanager
def output_lock(path, what: str = "output", wait: bool = False):
    """Hold an exclusive lock on ``path`` (file or folder, existing or not) for the block.

    ``wait``: when another run holds it, wait until it is released instead of refusing (a shared
    cache, such as two benches training the same model into one runs/ folder: the second then
    reuses what the first finished)."""
    lp = lock_path(path)
    lp.parent.mkdir(parents=True, exist_ok=True)
    f = open(lp, "a+")
    try:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if wait:
                fcntl.flock(f, fcntl.LOCK_EX)  # released when the other run ends, even if it is killed
                yield
                return
            raise OutputPathError(f"{what} {Path(path)} is being written by another run "
                                  f"(lock {lp} is held); wait for it or choose another path") from None
        yield
    finally:
        f.close()  # closing releases the lock


def unique_temp(path, suffix: str = ".partial") -> Path:
    """``<path><suffix>.<pid>.<random>``: a temporary name no other run can share."""
    path = Path(path)
    return path.with_name(f"{path.name}{suffix}.{os.getpid()}.{uuid.uuid4().hex[:8]}")


def json_marker(path, key: str, value=None) -> dict | None:
    """The JSON object in file ``path`` if it carries the toolkit's marker ``key`` (equal to ``value``,
    when given, else any non-empty value); None for a missing, unreadable or unmarked file."""
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or key not in doc:
        return None
    return doc if (doc[key] == value if value is not None else bool(doc[key])) else None


def refuse_foreign(path, what: str, why: str) -> None:
    raise OutputPathError(f"refusing to replace {path}: {why}; it was not written by hybrid-dyn as a {what}. "
                          f"Move it away or choose another output path")


def refuse_foreign_files(out_dir, what: str, is_own, marker: str = "config.json") -> None:
    """An output folder must be missing, empty, or hold only what ``is_own(path)`` proves a run of
    ours wrote (a finished folder has its ``marker`` file, config.json for a model, so it never reaches here)."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        refuse_foreign(out_dir, what, "it is a file, not a folder")
    if not out_dir.is_dir():
        return
    foreign = sorted(p.name for p in out_dir.iterdir() if not is_own(p))
    if foreign:
        refuse_foreign(out_dir, what, f"it holds {', '.join(foreign[:5])}{' ...' if len(foreign) > 5 else ''} "
                                      f"but no {marker}")


def _text_marker(what: str, body: str) -> str:
    digest = hashlib.sha256(body.encode()).hexdigest()
    return f"<!-- written by hybrid-dyn {what}; sha256 of the lines below: {digest} -->\n"


def owns_text(path, what: str) -> bool:
    """Whether text file ``path`` is one ``write_own_text(path, ..., what)`` wrote, unchanged since: its first
    line is the marker, which carries the sha256 of the rest (a file edited by hand is the user's now)."""
    try:
        head, sep, body = Path(path).read_text().partition("\n")
    except (OSError, ValueError):
        return False
    return bool(sep) and head + "\n" == _text_marker(what, body)


def check_own_text(path, what: str) -> None:
    """Refuse ``path`` as an output of ``what`` unless it is new (in a folder that exists) or a file
    :func:`owns_text` proves ours."""
    path = Path(path)
    if not path.parent.is_dir():
        raise OutputPathError(f"{path}: its folder {path.parent} does not exist")
    if path.is_dir():
        refuse_foreign(path, f"{what} output", "it is a folder")
    if (path.exists() or path.is_symlink()) and (path.is_symlink() or not owns_text(path, what)):
        refuse_foreign(path, f"{what} output", "it does not begin with the marker hybrid-dyn writes (or was "
                                               "edited since)")


def write_own_text(path, text: str, what: str) -> None:
    """Write ``text`` to ``path`` (a markdown file: the marker is an HTML comment, not shown) under its lock
    and atomically, after :func:`check_own_text` (under the lock)."""
    path = Path(path)
    with output_lock(path, f"{what} output"):
        check_own_text(path, what)
        tmp = unique_temp(path)
        tmp.write_text(_text_marker(what, text) + text)
        os.replace(tmp, path)
