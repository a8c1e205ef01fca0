"""The bench's identified rows on a log: identified on train and val, scored on test.

The reference is a direct ``identify`` call (what ``hybrid-dyn identify`` runs) on the same log.
"""
import json

import numpy as np
import pytest

from hybrid_dyn.bench.plan import BenchPlan
import hybrid_dyn as hd
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset

TINY_TRAINING = dict(max_epochs=1, max_batches_per_epoch=1, batch_size=64, progress=False, device="cpu", num_threads=1)


@pytest.mark.slow  # training and numba compilation: ~8 s
def test_bench_identifies_an_imported_log_on_train_and_val_and_scores_on_test(panda, identified_log, tmp_path):
    from hybrid_dyn.bench.catalog import select_rows
    from hybrid_dyn.bench.profiles import BenchProfile
    from hybrid_dyn.bench.plan import BenchContext
    from hybrid_dyn.bench.scoring import score_row, train_split_stats

    ds, model, _ = identified_log
    profile = BenchProfile(name="t", scenarios=("log",), recipe="plateau", train=TINY_TRAINING, workers=1)
    specs = {s.name: s for s in select_rows(families=("identified",))}
    for name in ("identified-consistent", "base-wrench-identified", "residual-rnea-identified",
                 "residual-rnea-bw-identified"):
        assert BenchPlan(profile).applies(specs[name], ds), name
    no_tau = type("D", (), {"fields": [f for f in ds.fields if f != "tau_m"], "meta": ds.meta})()
    assert not BenchPlan(profile).applies(specs["base-wrench-identified"], no_tau)  # the fit needs the logged torques
    ctx = BenchContext(profile, "log", ds, panda, tmp_path / "work", tmp_path / "data", log=lambda *a: None)
    norm = train_split_stats(ds)

    row = score_row(specs["identified-consistent"], ctx, norm)
    fitted, file = ctx.cache[("identified", "consistent")]
    n_fit = sum(len(i) for s in ("train", "val") for i in ds.split(s))
    assert fitted.fit["n_samples"] == n_fit  # train + val, never a test sample
    assert file.parent == tmp_path / "work" / "identified" and file.is_file()
    test = ds.split("test")
    err = np.concatenate([model.predict_torque(i.q, i.qd, i.qdd) - i.tau_m for i in test])
    assert row["rmse"] == pytest.approx(np.sqrt(np.mean(err ** 2)), rel=1e-9)

    res = score_row(specs["residual-rnea-identified"], ctx, norm)
    assert res["status"] == "ok" and "friction" in res["inputs"]
    trained = next((tmp_path / "work" / "models").glob("residual-rnea-identified-*"))
    config = json.loads((trained / "config.json").read_text())
    assert config["analytic_params"] == str(file.resolve()) and "friction" in config["prior"]


def test_identified_file_names_of_a_robot_variant_hold_no_brackets(tmp_path):
    from hybrid_dyn.bench.identified_rows import _identified
    from hybrid_dyn.bench.profiles import BenchProfile
    from hybrid_dyn.bench.plan import BenchContext

    bare = hd.load_robot("panda[tool=none]")
    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", bare, n_instances=3, n_samples=150, tip_forces=False))
    ctx = BenchContext(BenchProfile(name="t", scenarios=("log",)), "log", ds, bare, tmp_path / "work",
                       tmp_path / "data", log=lambda *a: None)
    fitted, file = _identified(ctx, "wls")
    assert not set("[]=;") & set(file.name)
    # Saved and read back as the variant: the bare flange, the hand not restored at its nominal mass.
    inst = ds.split("test")[0]
    np.testing.assert_allclose(fitted.to_robot().inverse_dynamics(inst.q, inst.qd, inst.qdd),
                               fitted.rigid_body_torque(inst.q, inst.qd, inst.qdd), rtol=0, atol=1e-9)
    assert _identified(BenchContext(ctx.profile, "log", ds, bare, tmp_path / "work", tmp_path / "data",
                                    log=lambda *a: None), "wls")[1] == file  # a rerun reads the file back
