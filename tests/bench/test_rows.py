"""The bench's row registry: a row is declared once and the runner, the report and
the profiles read that declaration; a declaration without what the row reads is refused."""
import ast
import csv
import dataclasses

import numpy as np
import pytest

from hybrid_dyn.bench.plan import BenchPlan
from hybrid_dyn.bench.catalog import ROWS, select_rows
from hybrid_dyn.bench.profiles import PROFILES, BenchProfile
from hybrid_dyn.bench.rows import Predictor, Row
from hybrid_dyn.errors import UsageError

from helpers import REPO


@pytest.fixture
def toy_row():
    """An analytic 'zero force' row, declared in one statement (and withdrawn after the test)."""
    row = ROWS.register(Row("zero-force", "tip_force", "analytic", needs=("q", "tip_force"), needs_urdf=False,
                      build=lambda ds, ctx: Predictor(predict=lambda insts: [np.zeros((len(i), 3)) for i in insts],
                                                      single_call=lambda inst, k: np.zeros(3), inputs="nothing")))
    yield row
    del ROWS[row.name]


@pytest.mark.slow  # ~3-5 s: a whole (tiny) bench run, report and figures included
def test_a_row_declared_once_runs_and_is_reported(toy_row, tmp_path, panda):
    from hybrid_dyn.bench.runner import run_bench
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset

    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=3, n_samples=40, seed=1))
    profile = dataclasses.replace(PROFILES["quick"], name="toy", scenarios=("synthetic",), families=(),
                                  rows=("zero-force",), workers=1)
    run_bench(profile, tmp_path / "report", work_root=tmp_path / "runs", dataset_provider=lambda s, p: ds,
              log=lambda m: None)
    with open(tmp_path / "report" / "results.csv", newline="") as f:
        row, = csv.DictReader(f)
    assert (row["model"], row["family"], row["inputs"], row["status"]) == ("zero-force", "analytic", "nothing", "ok")
    truth = np.concatenate([i["tip_force"] for i in ds.split("test")])
    assert float(row["rmse"]) == pytest.approx(np.sqrt(np.mean(truth ** 2)), rel=1e-5)  # the error of predicting 0
    md = (tmp_path / "report" / "tip_force.md").read_text()
    assert "| zero-force | analytic | nothing |" in md
    assert "analytic (zero-force)" in (tmp_path / "report" / "README.md").read_text()


def test_a_row_without_its_needs_is_refused():
    build = lambda ds, ctx: None  # noqa: E731
    with pytest.raises(UsageError, match="declare the dataset fields"):
        Row("no-needs", "tip_force", "analytic", needs=(), needs_urdf=True, build=build)
    with pytest.raises(TypeError):  # needs and needs_urdf have no default
        Row("no-needs", "tip_force", "analytic", build=build)
    with pytest.raises(UsageError, match="its target 'tau_m'"):
        Row("no-target", "joint_torque", "analytic", needs=("q",), needs_urdf=True, build=build)
    with pytest.raises(UsageError, match="unknown fields \\['qddd'\\]"):
        Row("typo", "tip_force", "analytic", needs=("qddd", "tip_force"), needs_urdf=True, build=build)
    with pytest.raises(UsageError, match="family must be one of"):
        Row("odd", "tip_force", "physics", needs=("tip_force",), needs_urdf=True, build=build)
    with pytest.raises(UsageError, match="declared twice"):
        ROWS.register(ROWS["base-wrench"])


def test_profiles_name_declared_rows_and_families_only():
    with pytest.raises(UsageError, match="unknown bench rows \\['no-such-row'\\]"):
        BenchProfile(name="t", scenarios=("s",), rows=("no-such-row",))
    with pytest.raises(UsageError, match="unknown bench families"):
        BenchProfile(name="t", scenarios=("s",), families=("nets",))
    # The reference row comes with its family; the real profile's rows by name.
    assert "seed-tip-11-raw" in [r.name for r in select_rows(families=("seed-net",))]
    real = PROFILES["real"]
    selected = [r.name for r in BenchPlan(real).selected_rows()]
    assert set(real.rows) <= set(selected) and "gp" in selected
    assert {r.family for r in BenchPlan(real).selected_rows() if r.name not in real.rows} == {"analytic", "identified"}


def _data(fields, robot="panda"):
    """What the bench reads of a dataset to choose its rows: its fields and its robot's name."""
    return type("Data", (), {"fields": list(fields), "meta": {"robot": robot}})()


def test_every_preset_is_a_bench_row_that_runs_where_its_fields_are():
    """A preset is a bench row by being declared: the bench runs it on data holding the preset's inputs
    and target, skips it naming any of them the data lack, and skips it on an arm known for data only
    exactly when it corrects a physics prior (which needs the URDF)."""
    from hybrid_dyn.bench.catalog import reference_label
    from hybrid_dyn.data import FIELD_UNITS
    from hybrid_dyn.description import ROBOTS
    from hybrid_dyn.learn.presets import PRESETS

    profile = BenchProfile(name="t", scenarios=("s",))
    every_field = tuple(FIELD_UNITS)
    data_only = ROBOTS.where(data_only=True)[0].name
    for p in PRESETS.values():
        row = ROWS[p.name]  # under the preset's own name, a trained row of its task
        assert row.trains and ("tip_force" if "tip_force" in p.targets else "joint_torque") == row.task, p.name
        assert BenchPlan(profile).skip_reason(row, _data((*p.inputs, *p.targets))) is None, p.name  # they suffice
        for field in dict.fromkeys((*p.inputs, *p.targets)):
            reason = BenchPlan(profile).skip_reason(row, _data(f for f in every_field if f != field))
            assert reason is not None and field in reason, (p.name, field, reason)
        reason = BenchPlan(profile).skip_reason(row, _data(every_field, robot=data_only))
        if p.prior is None:
            assert reason is None, (p.name, reason)  # a black box runs on any arm
        else:
            assert reason is not None and "URDF" in reason and data_only in reason, (p.name, reason)
        # A raw-sensor preset is the labelled reference the report sets apart; no other preset is.
        assert (reference_label(p.name) is not None) == p.raw_sensor, p.name


def test_the_timed_single_call_sees_the_run_in_order_from_its_start():
    from hybrid_dyn.bench.scoring import _median_call_us

    seen = []
    inst = np.zeros((30, 1))
    _median_call_us(lambda i, k: seen.append(k), inst, warmup_calls=12, n_calls=10)
    assert seen == list(range(22))  # 12 untimed calls, then 10 timed, never a sample skipped


def test_no_import_cycles_in_bench_and_between_dataset_and_store():
    root = REPO / "src" / "hybrid_dyn"
    for pkg in ("bench", "data"):
        mods = {p.stem for p in (root / pkg).glob("*.py")} - {"__init__"}
        graph = {}
        for m in mods:
            deps = set()
            for node in ast.walk(ast.parse((root / pkg / f"{m}.py").read_text())):  # function-level imports too
                if isinstance(node, ast.ImportFrom) and node.level == 1:
                    deps |= {node.module.split(".")[0]} if node.module else {a.name for a in node.names}
            graph[m] = deps & mods

        def reaches(a, b, seen):
            return any(n == b or (n not in seen and reaches(n, b, seen | {n})) for n in graph[a])

        assert not [m for m in sorted(mods) if reaches(m, m, set())], pkg


def test_pretrain_queues_the_dearest_architectures_first(monkeypatch):
    """The bench's training queue starts the DeLaN and wide LSTM rows before the MLPs, whatever order
    the rows come in, so that no core idles at the end while the other trains a DeLaN queued last.
    Observed in the order the queue hands the models to training (given here in declaration order)."""
    from hybrid_dyn.bench import training_queue
    from hybrid_dyn.learn.presets import PRESETS

    started = []
    monkeypatch.setattr(training_queue, "_train_job", lambda job: (started.append(job[2]), (job[2], None))[1])
    jobs = [("data", "panda", name, f"models/{name}", None, 1) for name in PRESETS]
    training_queue.pretrain(jobs, workers=1, log=lambda m: None)
    order = started
    assert sorted(order) == sorted(PRESETS)  # every model trained once
    assert order[0] == "delan-residual"
    assert order.index("delan-friction") < order.index("seed-tau-lstm-opt") < order.index("seed-tau-lstm") \
        < order.index("seed-tau-conv") < order.index("seed-tau-mlp")
    assert order.index("seed-tip-11") < order.index("seed-tip-9")  # 2 x 32 LSTM before 16 units, window 5
    assert order[-1] == "seed-tip-3"  # the narrowest MLP
