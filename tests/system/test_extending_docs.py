"""docs/extending.md followed word for word: in a copy of the repository, each section's **Write** steps write
the files it shows, its **Edit** steps change the one catalogue line it shows, and its **Run** steps run, each
succeeding; a help text it runs lists every name the section declares. Nothing else is edited."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.system

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "extending.md"
STEP = re.compile(r"^(Write|Edit) `([^`]+)`.*?\n\n```\w*\n(.*?)```|^Run:\n\n```bash\n(.*?)```", re.S | re.M)
DECLARED = re.compile(r"\b(?:Method|Family|Row|NetworkKind)\(\s*\"([^\"]+)\"")


def _sections() -> list[tuple[str, list]]:
    """(title, steps) of every section with steps; a step is (verb, path, text) or ("Run", None, commands)."""
    out = []
    for block in re.split(r"^## ", DOC.read_text(), flags=re.M)[1:]:
        steps = [(m[1], m[2], m[3]) if m[1] else ("Run", None, m[4]) for m in STEP.finditer(block)]
        if steps:
            out.append((block.splitlines()[0], steps))
    return out


def _copy_repository(to: Path) -> None:
    """The repository's files as a clone has them (tracked and untracked-but-not-ignored), into ``to``."""
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout.splitlines()
    for rel in files:
        if (ROOT / rel).is_file() and rel.split("/")[0] in ("src", "tests", "pyproject.toml"):
            (to / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / rel, to / rel)


def _edit(path: Path, new_line: str) -> None:
    """Replace the one line of ``path`` that begins as ``new_line`` does up to its first name."""
    head = new_line.split(",")[0]
    lines = path.read_text().splitlines(keepends=True)
    hits = [i for i, line in enumerate(lines) if line.startswith(head)]
    assert len(hits) == 1, f"{path}: {len(hits)} lines begin {head!r}"
    lines[hits[0]] = new_line + "\n"
    path.write_text("".join(lines))


def test_the_pages_table_lists_every_registry_the_source_declares():
    import importlib

    from hybrid_dyn.registry import Registry

    listed = re.findall(r"^\| `(hybrid_dyn\.[\w.]+)\.([A-Z_]+)` \|", DOC.read_text(), flags=re.M)
    for module, name in listed:
        assert isinstance(getattr(importlib.import_module(module), name), Registry), (module, name)
    declared = {(str(p.relative_to(ROOT / "src").with_suffix("")).replace("/", "."), m)
                for p in (ROOT / "src" / "hybrid_dyn").rglob("*.py")
                for m in re.findall(r"^([A-Z_]+) = Registry\(", p.read_text(), flags=re.M)}
    assert declared == set(listed)


@pytest.mark.slow  # three pytest runs and a bench, each in a fresh interpreter
def test_the_extending_page_followed_word_for_word(tmp_path, panda):
    from hybrid_dyn.data.synthetic import make_synthetic_dataset

    sections = _sections()
    titles = [t for t, _ in sections]
    assert titles[:3] == ["A tip-force estimator method", "A bench family and its row", "A network kind"], titles
    clone = tmp_path / "clone"
    _copy_repository(clone)
    data = make_synthetic_dataset(tmp_path / "data", panda, n_instances=4, n_samples=120, seed=1)
    env = {**os.environ, "PYTHONPATH": str(clone / "src"),
           "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])}
    for title, steps in sections:
        names = [n for verb, _, text in steps if verb == "Write" for n in DECLARED.findall(text)]
        for verb, rel, text in steps:
            if verb == "Write":
                assert not (clone / rel).exists(), f"{title}: {rel} is the toolkit's own file"
                (clone / rel).write_text(text)
            elif verb == "Edit":
                assert text.count("\n") == 1, f"{title}: an edit is one line"
                _edit(clone / rel, text.rstrip("\n"))
            else:
                for command in filter(None, (c.strip() for c in text.splitlines())):
                    command = re.sub(r"\bDIR\b", str(data), command)
                    done = subprocess.run(command, shell=True, cwd=clone, env=env, capture_output=True, text=True,
                                          timeout=900)
                    assert done.returncode == 0, f"{title}: {command}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
                    if command.startswith("python -m pytest"):
                        assert re.search(r"\d+ passed", done.stdout) and "failed" not in done.stdout, done.stdout
                    if command.endswith("--help"):
                        flat = "".join(done.stdout.split())  # argparse wraps lines at hyphens
                        assert all(n in flat for n in names), (title, names)
