"""The committed reports/: every folder indexed with its command, bench folders hold only what the
bench writes, and no committed report or document names a folder of the machine that wrote it."""
import re
from pathlib import Path

import pytest

from helpers import REPO

pytestmark = pytest.mark.system

REPORTS = REPO / "reports"
NOT_COMMITTED = {"predictions.h5"}  # .gitignore: every report's predictions stay out of git
# What hybrid-dyn bench and hybrid-dyn report write into a report folder (runner.py, report.py).
# (free_motion.csv/.md and uncalibrated_free_motion.md: the real report's section "Tip force in free motion", by
# benchmarks/free_motion.py and benchmarks/uncalibrated_free_motion.py, which the report's README draws:
# bench/free_motion.py)
BENCH_FILES = re.compile(r"^(results\.csv|run\.json|curves\.json|README\.md|seed_comparison\.md|predictions\.h5"
                         r"|(joint_torque|tip_force)\.(md|tex)|(uncalibrated_)?free_motion\.(csv|md)|[\w.+-]+\.png)$")
COMMAND = re.compile(r"`(hybrid-dyn (bench|study|report|compare)\b[^`]*|python (benchmarks|checks)/\w+\.py[^`]*)`")
# Absolute paths of a machine's own folders (a user's example such as /path/arm.urdf is not one).
MACHINE_PATH = re.compile(r"(?:^|(?<=[\s`'\"(\[=,:]))/(?:work|home|tmp|Users|root|mnt|scratch|private|var/folders)/")
TEXT = (".md", ".json", ".csv", ".tex", ".txt", ".toml")
# Bench files written before run.json recorded relative dataset paths, awaiting their regeneration (every
# committed report has been regenerated since). The list only shrinks: a file here that no longer
# holds a machine path fails the test until it is taken off.
AWAITING_REGENERATION = set()


def _folders() -> set:
    """Every folder under reports/ that holds a committed file, relative to reports/."""
    out = set()
    for f in REPORTS.rglob("*"):
        rel = f.relative_to(REPORTS)
        if f.is_file() and f.name not in NOT_COMMITTED and rel.parts[0] != "quick" and f.parent != REPORTS:
            out.add(f.parent.relative_to(REPORTS).as_posix())
    return out


def _index() -> dict:
    """reports/README.md's table rows: folder -> the row's text."""
    rows = {}
    for line in (REPORTS / "README.md").read_text().splitlines():
        m = re.match(r"\| `([\w./-]+)/` \|", line)
        if m:
            rows[m.group(1)] = line
    return rows


def test_every_report_folder_is_indexed_with_the_command_that_writes_it():
    index = _index()
    for folder in sorted(_folders()):
        # a folder is indexed itself or inside an indexed folder (a study's kept variant report)
        listed = [f for f in index if folder == f or folder.startswith(f + "/")]
        assert listed, f"reports/{folder} is not in reports/README.md"
    for folder, row in index.items():
        assert (REPORTS / folder).is_dir(), f"reports/README.md lists reports/{folder}, which does not exist"
        assert COMMAND.search(row), f"reports/README.md: no command that regenerates reports/{folder}"
        assert re.search(r"`[0-9a-f]{7,}`", row), f"reports/README.md: no commit for reports/{folder}"


def test_a_bench_profiles_folder_holds_only_what_the_bench_writes():
    from hybrid_dyn.bench.profiles import PROFILES
    from hybrid_dyn.bench.studies import STUDIES

    for name in PROFILES:
        folder = REPORTS / name
        if not folder.is_dir() or name == "quick":
            continue
        # A study that extends this report keeps its summary in a folder of its own inside it (Study.out).
        studies = {Path(st.default_out()).name for st in STUDIES.values() if Path(st.default_out()).parent == Path("reports") / name}
        others = sorted(f.name for f in folder.iterdir()
                        if not BENCH_FILES.match(f.name) and not (f.is_dir() and f.name in studies))
        assert not others, f"reports/{name} holds files hybrid-dyn bench does not write: {others}"
        assert (folder / "run.json").is_file() and (folder / "results.csv").is_file()


def _committed_text_files():
    for root in ("reports", "docs", "checks"):
        for f in sorted((REPO / root).rglob("*")):
            if f.is_file() and f.suffix in TEXT and f.name not in NOT_COMMITTED:
                yield f
    for f in (REPO / "README.md", REPO / "benchmarks" / "README.md"):
        if f.is_file():
            yield f


def test_no_committed_report_or_document_names_a_folder_of_the_machine_that_wrote_it():
    offenders = {}
    for f in _committed_text_files():
        hits = [i for i, line in enumerate(f.read_text(errors="replace").splitlines(), 1) if MACHINE_PATH.search(line)]
        if hits:
            offenders[f.relative_to(REPO).as_posix()] = hits[:5]
    new = {k: v for k, v in offenders.items() if k not in AWAITING_REGENERATION}
    assert not new, f"machine paths (file: lines): {new}"
    fixed = sorted(AWAITING_REGENERATION - set(offenders))
    assert not fixed, f"{fixed} no longer hold a machine path: take them off AWAITING_REGENERATION"


@pytest.mark.parametrize("text, found", [
    ("read from `/work/wt-default/data/x`", True), ('"path": "/tmp/hybrid_dyn_real_cache"', True),
    ("--out /home/me/r.md", True), ("read from `data/x`", False), ("`../shared/data/real`", False),
    ("a user's URDF `/path/arm.urdf`", False), ("https://example.org/work/x", False), ("N/sqrt(s)", False)])
def test_the_machine_path_pattern(text, found):
    assert bool(MACHINE_PATH.search(text)) is found
