"""Hybrid rows and their physics priors in the bench: declared priors, the report's lines."""
import pytest

from hybrid_dyn.bench.catalog import ROWS
from hybrid_dyn.bench.hybrids import hybrid_lines
from hybrid_dyn.bench.rows import prior_kept_text


def test_every_declared_prior_is_a_row_of_the_same_task():
    hybrids = {name: r.prior_row for name, r in ROWS.items() if r.prior_row}
    # The rows the issue names as hybrids on a physics prior all declare it.
    assert hybrids["residual-rnea"] == "rnea"
    assert hybrids["residual-rnea-identified"] == hybrids["gp-residual-identified"] == "identified-consistent"
    for name, prior in hybrids.items():
        assert prior in ROWS and ROWS[prior].task == ROWS[name].task, name
        assert not ROWS[prior].trains, name  # a prior is physics: nothing trained


@pytest.mark.parametrize("kept,text", [([True] * 7, "all"), ([False] * 7, "none"),
                                       ([False, True, False, False, True, False, False], "joints 2, 5")])
def test_prior_kept_in_words(kept, text):
    assert prior_kept_text(kept) == text


def _row(model, rmse, **kw):
    return {"scenario": "s", "task": "joint_torque", "model": model, "status": "ok", "rmse": str(rmse), **kw}


def test_report_sets_each_hybrid_against_its_prior_and_says_when_it_kept_it():
    rows = [_row("rnea", 0.5), _row("residual-rnea", 0.4, prior_kept="none"),
            _row("identified-consistent", 0.3), _row("gp-residual-identified", 0.3, prior_kept="all"),
            _row("residual-rnea-identified", 0.27, prior_kept="joints 7"), _row("gp", 6.8)]
    lines = [line for line in hybrid_lines(rows) if line.startswith("- ")]
    # One line per hybrid beside its prior, in results order (gp has no prior; the priors are not hybrids).
    named = [next(m for m in ("residual-rnea-identified", "gp-residual-identified", "residual-rnea")
                  if f"`{m}`" in line) for line in lines]
    assert named == ["residual-rnea", "gp-residual-identified", "residual-rnea-identified"]
    # Each: its prior, both test RMSEs and their ratio, and what validation kept of the prior.
    facts = [("`rnea`", "0.4000", "0.5000", "x0.800"), ("`identified-consistent`", "0.3000", "x1.000"),
             ("`identified-consistent`", "0.2700", "0.3000", "x0.900", "joints 7")]
    for line, expected in zip(lines, facts):
        assert all(fact in line for fact in expected), (line, expected)
    assert "corrected" in lines[0] and "kept" not in lines[0]          # prior_kept none
    assert "kept the prior" in lines[1] and "corrected" not in lines[1]  # prior_kept all
    assert "kept the prior" in lines[2] and "corrected" in lines[2]      # prior_kept on some joints
    # A prior that did not run (failed, or not selected): no comparison is claimed.
    assert hybrid_lines([_row("residual-rnea", 0.4), {**_row("rnea", 0.5), "status": "failed"}]) == []


def test_bench_runs_some_scenarios_of_a_profile_and_its_report_says_so(tmp_path, capsys):
    import dataclasses

    from hybrid_dyn.bench.profiles import PROFILES
    from hybrid_dyn.bench.report import _command
    from hybrid_dyn.cli import main as cli_main

    assert cli_main(["bench", "--profile", "real", "--scenarios", "real-nope", "--out", str(tmp_path / "r")]) == 2
    assert "not among profile 'real'" in capsys.readouterr().err and not (tmp_path / "r").exists()
    narrowed = dataclasses.replace(PROFILES.lookup("real"), scenarios=("real-panda",), families=("identified",),
                                   rows=("rnea",))
    assert _command(narrowed.to_dict()) == ("hybrid-dyn bench --profile real --scenarios real-panda "
                                            "--families identified --rows rnea")
    assert _command(PROFILES.lookup("real").to_dict()) == "hybrid-dyn bench --profile real"
