"""Kill-and-resume matrix: `generate` and `train` killed mid-run by SIGKILL, SIGINT or SIGTERM,
then run again, must resume to the uninterrupted run's bytes with no orphan process and no temporary
file left (the checks and the commands: helpers/fault_injection.py).

The whole matrix is 24 cases (generate with 1 and 2 workers, train with one preset of each family, under
each signal), about 11 minutes on 2 cores: more than the suite's budget. `make test-all` (and CI) runs the cases
marked below as DEFAULT, one per command and none that another test already covers (a SIGKILLed
generate resuming to the same bytes: sim/test_generator_dataset.py; a SIGKILLed train resuming:
learn/test_train.py; a killed generate's workers dying: sim/test_executors.py). The rest run with
``pytest --fault-matrix`` (or ``-m fault_matrix --fault-matrix``), before a release or after a change to
checkpoints, output files or worker processes.
"""
from __future__ import annotations

import sys

import pytest

from helpers import fault_injection as fi

pytestmark = [pytest.mark.system, pytest.mark.slow,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")]

# The cases of every `make test-all`: SIGINT (Ctrl-C) of generate, SIGTERM (a scheduler's stop) of train.
DEFAULT = {"generate-w1-SIGINT", "train-seed-tip-5-SIGTERM"}


def _param(case: fi.Case):
    marks = () if case.key in DEFAULT else (pytest.mark.fault_matrix,)
    return pytest.param(case, id=case.key, marks=marks)


class References:
    """The uninterrupted reference runs, each made once, when a case first needs it; the 1-worker
    generate reference is also train's dataset."""

    def __init__(self, work):
        self.work, self.done = work, {}

    @property
    def data(self):
        return self.get(fi.Case("generate", "", 1))

    def get(self, case: fi.Case):
        key = case.reference_key()
        if key not in self.done:
            out, log = self.work / f"ref-{key}", self.work / f"ref-{key}.log"
            data = None if case.command == "generate" else self.data
            rc, seconds = fi.run_to_end(fi.case_argv(case, out, data), log)
            assert rc == 0, f"the reference run {key} failed (exit {rc}) after {seconds:.0f} s:\n{fi.log_tail(log)}"
            self.done[key] = out
        return self.done[key]


@pytest.fixture(scope="module")
def references(tmp_path_factory):
    return References(tmp_path_factory.mktemp("fault-references"))


@pytest.mark.parametrize("case", [_param(c) for c in fi.matrix()])
def test_a_killed_run_resumes_to_the_uninterrupted_runs_bytes(case, references, tmp_path):
    reference = references.get(case)
    data = references.data if case.command == "train" else None
    result = fi.run_case(case, reference, data, tmp_path)
    notes = fi.failure_notes(result)
    assert not notes, "\n".join([f"{case.key}:", *notes, "log tail:", result.get("log_tail", "")])
    # Each check, stated (failure_notes names what failed; these say what passing means).
    killed = result["killed"]
    assert killed["signal_sent"] and killed["mid_run"]          # the signal came while work was under way
    assert result["resumed"] and result["resume_exit_status"] == 0  # the rerun finished, keeping that work
    assert result["bytes"]["identical"] and result["bytes"]["compared"] > 0
    assert killed["orphans"] == [] and result["temporaries"] == []


@pytest.mark.fault_matrix
def test_generate_references_with_1_and_2_workers_are_identical(references):
    one = references.get(fi.Case("generate", "", 1))
    two = references.get(fi.Case("generate", "", 2))
    same = fi.compare_folders(one, two)
    assert same["identical"], same
