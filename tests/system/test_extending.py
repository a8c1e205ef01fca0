"""Extending the toolkit, all four at once (docs/extending.md): a toy estimator method with a new bandwidth
parameter, a toy network kind, a toy family and a toy row, each declared in one place (the ``toys`` fixture),
are found by the estimator, the bench's results.csv, the report and ``compare`` with no other edit; withdrawn,
they leave nothing derived behind.

The family is reached two ways: a hand-declared row, and a preset of the toy kind whose row the bench declares
itself (``bench/learned_rows.py`` listens to the presets). The toy method's own row is the analytic row that
the toy family's rows are compared against. Each part is told more fully by its own test:
tests/analytic/test_extending_method.py, tests/learn/test_extending_kind.py, tests/bench/test_extending_bench.py.
"""
import csv
import shutil

import numpy as np
import pytest
from torch import nn

from hybrid_dyn.analytic.bandwidth import BANDWIDTHS, BandwidthParameter
from hybrid_dyn.analytic.method_declaration import Method, MethodStream
from hybrid_dyn.analytic.methods import TIP_FORCE_METHODS
from hybrid_dyn.bench import report as report_mod
from hybrid_dyn.bench.compare import compare_reports
from hybrid_dyn.bench.families import FAMILIES, Family
from hybrid_dyn.bench.profiles import PROFILES, BenchProfile
from hybrid_dyn.bench.rows import ROWS, Predictor, Row
from hybrid_dyn.learn import kinds
from hybrid_dyn.learn.nets import fc_head
from hybrid_dyn.learn.presets import PRESETS, TIP_INPUTS, Preset

pytestmark = pytest.mark.system

HZ = 100.0  # the tiny dataset's record rate [Hz]
TOYS = {"method": "static-base", "parameter": "toy_gain", "kind": "window-mean", "family": "toy-net",
        "preset": "toy-window-mean", "row": "toy-mean-force"}


# ---------------------------------------------------------------- the toy method and its bandwidth parameter
class StaticBase(MethodStream):
    """F = -(R w + m g), the tared base sensor's force less the arm's weight, low-passed by K = toy_gain [1/s]."""

    def choose(self, noise):  # "auto": the method's rule
        return 0.2 * self.rate_hz

    def reset(self):
        self._f = None

    def step(self, q, qd, qdd, w, tau):
        r = self.robot
        raw = -(r.base_wrench_to_root(w)[:3] + r.total_mass * np.asarray(r.model_ff.gravity.linear))
        a = min(self.value * self.dt, 1.0)
        self._f = raw if self._f is None else self._f + a * (raw - self._f)
        return self._f.copy()

    def batch(self, q, qd, qdd, w, tau):
        self.reset()
        return np.stack([self.step(q[k], qd[k], None, w[k], None) for k in range(len(q))])

    def settle_calls(self, sensors=()):
        return int(np.ceil(np.log(0.01) / np.log(1.0 - min(self.value * self.dt, 0.99))))


# ---------------------------------------------------------------- the toy network kind
class WindowMeanNet(nn.Module):
    """The window's mean over time, then FC layers (a net kind has a ``head``)."""

    def __init__(self, n_in, n_out, p):
        super().__init__()
        self.head = fc_head(n_in, p.fc_layers, p.fc_units, n_out, p.activation)

    def forward(self, x):  # (B, L, F), standardized
        return self.head(x.mean(1))


# ---------------------------------------------------------------- the toy row
def _mean_force(ds, ctx) -> Predictor:
    """Every sample's tip force is the train split's mean [N] (nothing but numpy)."""
    mean = np.concatenate([i["tip_force"] for i in ds.split("train")]).mean(axis=0)
    return Predictor(predict=lambda insts: [np.tile(mean, (len(i), 1)) for i in insts],
                     single_call=lambda inst, k: mean, inputs="nothing")


@pytest.fixture
def toys():
    """The one place each toy is declared; withdrawn after the test, what was derived from them checked gone."""
    BANDWIDTHS.register(BandwidthParameter(TOYS["parameter"], "1/s", "the toy's low-pass gain K",
                                           val_grid=lambda rate_hz: (0.05 * rate_hz, 0.5 * rate_hz)))
    TIP_FORCE_METHODS.register(Method(TOYS["method"], "a toy: the base sensor's force less the arm's weight",
                                      reads=("base_wrench",), any_of=False, needs_qdd=False, tares=True,
                                      parameter=TOYS["parameter"], make=StaticBase))
    kinds.NETWORK_KINDS.register(kinds.NetworkKind(
        TOYS["kind"], "the window's mean over time, then FC layers (a toy)",
        build=kinds.single_net(lambda p, n_in, n_out: WindowMeanNet(n_in, n_out, p)),
        fast=lambda parts: (lambda x: x.mean(0)), clips_gradients=False, cost_rank=0, search=kinds.search_fc,
        budget_steps=200, sequence=True, needs_front=False))
    FAMILIES.register(Family(TOYS["family"], "a toy learned family (tests)", fitted=True, in_studies=True,
                             figures=("traces",)))
    ROWS.register(Row(TOYS["row"], "tip_force", TOYS["family"], needs=("q", "tip_force"), needs_urdf=False,
                build=_mean_force))
    PRESETS.register(Preset(TOYS["preset"], TOYS["kind"], tuple(TIP_INPUTS), ("tip_force",), window=5, fc_layers=1,
                           fc_units=8, family=TOYS["family"]))
    try:
        yield TOYS
    finally:
        for registry, name in ((PRESETS, TOYS["preset"]), (ROWS, TOYS["row"]), (FAMILIES, TOYS["family"]),
                               (kinds.NETWORK_KINDS, TOYS["kind"])):
            if name in registry:
                registry.unregister(name)
        if TOYS["method"] in TIP_FORCE_METHODS:
            TIP_FORCE_METHODS.unregister(TOYS["method"])
        if TOYS["parameter"] in BANDWIDTHS:
            BANDWIDTHS.unregister(TOYS["parameter"])
    _assert_nothing_left()


def _assert_nothing_left():
    """Nothing the toys declared, nor anything derived from them, is left in a registry or a derived list."""
    m, fam = TOYS["method"], TOYS["family"]
    assert TOYS["parameter"] not in BANDWIDTHS and m not in TIP_FORCE_METHODS
    assert TOYS["kind"] not in kinds.NETWORK_KINDS and TOYS["preset"] not in PRESETS
    for row in (m, f"{m}-val", TOYS["preset"], TOYS["row"]):
        assert row not in ROWS, row
    assert fam not in FAMILIES
    assert not any(fam in p.families for p in PROFILES.values())


def _results(folder) -> dict:
    with open(folder / "results.csv", newline="") as f:
        return {r["model"]: r for r in csv.DictReader(f)}


def test_toys_declared_once_reach_estimator_bench_report_and_compare(toys, panda, tmp_path, monkeypatch):
    from hybrid_dyn.bench.runner import run_bench
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.estimator import TipForceEstimator

    m, fam, preset = toys["method"], toys["family"], toys["preset"]
    # Declared, derived: the method's two bench rows, the preset's row, the family in every list read from it.
    assert ROWS[m].family == "analytic" and ROWS[f"{m}-val"].reference
    assert ROWS[preset].family == fam and ROWS[preset].trains
    assert [p.name for p in PRESETS.where(family=fam)] == [preset]
    assert fam in FAMILIES.names(fitted=True, in_studies=True)  # a study's and compare's families
    assert not any(fam in p.families for p in PROFILES.values())  # a shipped profile names its own

    # 11 s runs: the estimator refuses its 0.5 s window, and a row answering under 95 % is no best row.
    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=6, n_samples=1100, record_hz=HZ,
                                             seed=3, noise=0.01, contact_free_s=0.6))

    # The estimator: the method by its name, its new parameter a keyword, honoured (not silently "auto").
    run = ds.split("test")[0]
    for settings, gain in (({}, 0.2 * HZ), ({toys["parameter"]: 7.0}, 7.0)):
        est = TipForceEstimator.analytic(panda, m, call_hz=HZ, encoder_resolution=0.0, **settings)
        forces = np.stack([est.estimate_tip_force(run.q[k], run.qd[k], base_wrench=run.base_wrench[k], t=k / HZ)
                           for k in range(len(run))])
        assert est.bandwidth == gain and np.all(np.isfinite(forces[-1]))

    # The bench, restricted to the toys: the toy family (the hand-declared row and the preset's) and the method's
    # two rows, two training steps. The figures are matplotlib's slow part and not what this test reads.
    monkeypatch.setattr(report_mod, "_figures", lambda *a, **k: [])
    monkeypatch.setattr(report_mod, "learning_curve_figures", lambda *a, **k: [])
    profile = BenchProfile(name="toys", scenarios=("synthetic",), families=(fam,), rows=(m, f"{m}-val"), workers=1,
                           train=dict(budget_steps=2, budget_evals=1, batch_size=64, progress=False))
    a = tmp_path / "a"
    run_bench(profile, a, work_root=tmp_path / "runs", dataset_provider=lambda s, p: ds, log=lambda msg: None)
    results = _results(a)
    assert set(results) == {m, f"{m}-val", toys["row"], preset}
    assert {name: (r["family"], r["status"]) for name, r in results.items()} == {
        m: ("analytic", "ok"), f"{m}-val": ("analytic", "ok"), toys["row"]: (fam, "ok"), preset: (fam, "ok")}
    assert "toy_gain" in results[f"{m}-val"]["inputs"] and "chosen on val" in results[f"{m}-val"]["inputs"]
    assert int(results[preset]["n_params"]) > 0  # the toy kind's net, trained

    # The report, redrawn from the files (what `hybrid-dyn report` runs): every toy row in the tip-force table,
    # the toy family among the best per family.
    (a / "tip_force.md").unlink()
    report_mod.rebuild_report(a, log=lambda msg: None)
    table = (a / "tip_force.md").read_text()
    for row, family in ((m, "analytic"), (toys["row"], fam), (preset, fam)):
        low = float(results[row]["answered_share"]) < 0.95  # marked so (metrics.ANSWERED_FLOOR)
        assert f"| {row}{' §' if low else ''} | {family} |" in table, row
    assert f"| {m}-val" in table
    assert f"{fam} (" in (a / "README.md").read_text()

    # compare (what `hybrid-dyn compare` prints): the toy family's rows against the toy method, the best
    # analytic row of both reports; a second report of the same rows gives each row a ratio change of 1.
    b = tmp_path / "b"
    shutil.copytree(a, b)
    text = compare_reports(a, b)
    assert f"Best analytic row: a `{m}`" in text
    for row in (toys["row"], preset):
        line = next(x for x in text.splitlines() if x.startswith(f"| {row} |"))
        assert line.startswith(f"| {row} | {fam} |") and line.endswith("| 1.00x |")
