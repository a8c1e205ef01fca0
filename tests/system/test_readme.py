"""The README is a front door a newcomer reads in one screen: at most 8 KB, no line over 300 characters, and every
number of its headline table equal to the report it links to.

The headline table is generic, so that a row from any report can be added: each row names its csv file (a markdown
link, relative to the repository root), the csv row it reads (``key=value`` pairs that select exactly one row) and
the column; its value cell holds the number as printed, to the digits it shows. A row such as
``| Tip force in free motion, Panda | 0.123 N | [reports/real/free_motion.csv](reports/real/free_motion.csv) |
robot=panda torque_model=rnea method=momentum-observer | phantom_rms_N |`` is checked like the others.
"""
from __future__ import annotations

import csv
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
MAX_BYTES = 8 * 1024
MAX_LINE = 300
COLUMNS = ("result", "value", "csv", "row", "column")  # the headline table's header, in this order
LINK = re.compile(r"\[[^\]]*\]\(([^)]+\.csv)\)")
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def headline_rows(text: str) -> list[dict]:
    """The headline table's rows, each a dict by :data:`COLUMNS`; the table is the one whose header is COLUMNS."""
    lines = text.splitlines()
    starts = [i for i, line in enumerate(lines) if line.startswith("|") and tuple(_cells(line)) == COLUMNS]
    assert len(starts) == 1, f"README: {len(starts)} tables with the header {COLUMNS}"
    rows = []
    for line in lines[starts[0] + 2:]:
        if not line.startswith("|"):
            break
        cells = _cells(line)
        assert len(cells) == len(COLUMNS), f"README headline row has {len(cells)} cells, not {len(COLUMNS)}: {line}"
        rows.append(dict(zip(COLUMNS, cells)))
    return rows


def reported_value(row: dict) -> tuple[str, float]:
    """(the csv's text, its value) for one headline row: the one csv row whose fields equal the row's ``key=value``
    pairs, at the row's column. A link to a missing file, a key no csv column has, no match or several are errors."""
    link = LINK.search(row["csv"])
    assert link, f"headline row {row['result']!r}: no link to a .csv file in {row['csv']!r}"
    path = ROOT / link[1]
    assert path.is_file(), f"headline row {row['result']!r} links to {link[1]}, which does not exist"
    keys = dict(pair.split("=", 1) for pair in row["row"].strip("`").split())
    assert keys, f"headline row {row['result']!r}: no key=value pairs to select a csv row"
    column = row["column"].strip("`")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        unknown = sorted(set(keys) - set(reader.fieldnames or ()) | ({column} - set(reader.fieldnames or ())))
        assert not unknown, f"headline row {row['result']!r}: {link[1]} has no column {unknown}"
        hits = [r for r in reader if all(r[k] == v for k, v in keys.items())]
    assert len(hits) == 1, f"headline row {row['result']!r}: {len(hits)} rows of {link[1]} match {keys}"
    return link[1], float(hits[0][column])


def test_readme_is_at_most_8_kb_and_no_line_is_over_300_characters():
    data = README.read_bytes()
    assert len(data) <= MAX_BYTES, f"README.md is {len(data)} bytes, more than {MAX_BYTES}"
    long = [(i, len(line)) for i, line in enumerate(data.decode().splitlines(), 1) if len(line) > MAX_LINE]
    assert not long, f"README.md lines over {MAX_LINE} characters (line, length): {long}"


def test_every_headline_number_equals_the_report_it_links_to():
    rows = headline_rows(README.read_text())
    assert len(rows) >= 4, rows
    for row in rows:
        shown = NUMBER.search(row["value"])
        assert shown, f"headline row {row['result']!r}: no number in {row['value']!r}"
        digits = len(shown[0].partition(".")[2])
        source, value = reported_value(row)
        assert f"{value:.{digits}f}" == shown[0], \
            f"README says {shown[0]} for {row['result']!r}; {source} has {value} ({value:.{digits}f})"


def test_the_figure_and_every_page_the_readme_maps_exist():
    text = README.read_text()
    pages = re.findall(r"^\| `([^`]+\.md)` \|", text, flags=re.M)
    assert len(pages) >= 10 and all((ROOT / p).is_file() for p in pages), [p for p in pages if not (ROOT / p).is_file()]
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(images) == 1 and images[0].startswith("reports/") and (ROOT / images[0]).is_file(), images
    for row in headline_rows(text):
        assert (ROOT / LINK.search(row["csv"])[1]).is_file()


@pytest.mark.parametrize("value, ok", [("0.212 N", True), ("0.211 N", False), ("0.21 N", True), ("0.2115 N", True), ("0.2116 N", False)])
def test_the_number_check_reads_the_csv_and_fails_on_a_wrong_digit(value, ok):
    """The check itself: a README value off in its last shown digit is caught (0.211514 prints 0.212, 0.21, 0.2115)."""
    row = {"result": "t", "value": value, "csv": "[r](reports/default/results.csv)",
           "row": "task=tip_force scenario=paper-ext model=momentum-observer", "column": "rmse"}
    shown = NUMBER.search(value)[0]
    _, got = reported_value(row)
    assert (f"{got:.{len(shown.partition('.')[2])}f}" == shown) is ok


def test_a_row_matching_no_or_several_csv_rows_is_refused():
    base = {"result": "t", "value": "1 N", "csv": "[r](reports/default/results.csv)", "column": "rmse"}
    with pytest.raises(AssertionError, match="0 rows"):
        reported_value({**base, "row": "task=tip_force scenario=paper-ext model=no-such-row"})
    with pytest.raises(AssertionError, match="rows of"):
        reported_value({**base, "row": "task=tip_force scenario=paper-ext"})
    with pytest.raises(AssertionError, match="no column"):
        reported_value({**base, "row": "robot=panda"})
