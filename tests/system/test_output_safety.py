"""Output paths: concurrent runs, and the rule that the toolkit replaces only what it wrote.

Each test builds its own tiny data. The concurrency tests are deterministic: the
second run starts while the first is provably inside its run (it waits on an
event), or both writers are made to collide on the same file.
"""
import hashlib
import json
import multiprocessing as mp
import os
from pathlib import Path

import h5py
import numpy as np
import pytest

from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.data import import_log, load_dataset
from hybrid_dyn.data.dataset import DatasetError
from hybrid_dyn.errors import OutputPathError, UsageError
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.generator_config import PulseConfig
from hybrid_dyn.sim.scenarios import scenario_config

from helpers.files import generate_in_child
from helpers.messages import says
from helpers.timelimit import time_limit

pytestmark = pytest.mark.system

TINY = dict(n_instances=2, trajectories=(1, 1), standstill=0.2, speed_scale=(0.5, 0.6),
            pulses=PulseConfig(gap=(0.5, 1.0), sigma=(0.2, 0.4)))


def tiny_config(seed=0, **kw):
    # The legacy sensors' files: their middle lies in compressed chunks (test_rerun_repairs_...), where a
    # quantized q's better-compressed file has its attributes.
    return scenario_config("paper-ext-ideal", "quick", seed=seed, **{**TINY, **kw})


def read_every_instance(path: Path) -> None:
    """Open the dataset (checksums verified) and decompress every array of every instance."""
    ds = load_dataset(path)
    for split in ("train", "val", "test"):
        for inst in ds.split(split):
            for name in ds.fields:
                np.asarray(inst[name])
            inst.truth


def sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def quiet(_msg):
    pass


# ---------------------------------------------------------------- generate: concurrency
def test_second_generate_into_one_folder_is_refused_naming_the_lock(tmp_path):
    out = tmp_path / "ds"
    ctx = mp.get_context("spawn")
    started, go, result = ctx.Event(), ctx.Event(), ctx.Queue()
    first = ctx.Process(target=generate_in_child, args=(tiny_config(), str(out), started, go, result))
    first.start()
    try:
        assert started.wait(120), "the first run never started"
        # The first run is inside generate_dataset: a second one must be refused at once.
        with pytest.raises(OutputPathError, match=r"being written by another run \(lock .*\.ds\.lock is held\)"):
            generate_dataset(tiny_config(), out, progress=False, log=quiet)
    finally:
        go.set()
        first.join(120)
    assert result.get(timeout=5) == "ok"
    read_every_instance(out)
    # The lock is gone with the first run: a rerun resumes (verifies, keeps every file).
    before = {p.name: p.read_bytes() for p in (out / "instances").iterdir()}
    generate_dataset(tiny_config(), out, progress=False, log=quiet)
    assert {p.name: p.read_bytes() for p in (out / "instances").iterdir()} == before


def test_instance_temporary_is_unique_and_hashed_before_the_rename(tmp_path, monkeypatch):
    """A worker on a shared folder (Ray), where the driver's lock does not reach: another run
    writes the same instance at the same moment. Its temporary is not ours, and its rename
    landing on the file right after ours must not make our record vouch for its bytes."""
    from hybrid_dyn.sim import generator

    config_json = json.dumps(tiny_config().to_dict(), sort_keys=True)
    clean = generator._instance_job(config_json, 0, str(tmp_path / "clean"))  # the bytes this job writes
    out = tmp_path / "shared"
    generate_dataset(tiny_config(), out, progress=False, log=quiet)  # a dataset whose instance 0 is rewritten
    final = out / "instances" / "inst_00000.h5"
    foreign_tmp = out / "instances" / "inst_00000.h5.partial"  # the other run's temporary, still open
    foreign_tmp.write_bytes(b"another run's half-written file")
    real_replace = os.replace

    def replace_then_other_run_lands(src, dst):
        real_replace(src, dst)
        if Path(dst) == final:  # the other run's rename comes right after ours
            other = out / "instances" / "other-run"
            other.write_bytes(b"not an HDF5 file")
            real_replace(other, dst)

    monkeypatch.setattr(os, "replace", replace_then_other_run_lands)
    rec = generator._instance_job(config_json, 0, str(out))
    monkeypatch.setattr(os, "replace", real_replace)
    assert foreign_tmp.read_bytes() == b"another run's half-written file"
    assert rec["sha256"] == clean["sha256"] == sha(tmp_path / "clean" / "instances" / "inst_00000.h5")
    assert sha(final) != rec["sha256"]
    # A rerun finds the file does not match its record and regenerates it.
    messages = []
    generate_dataset(tiny_config(), out, progress=False, log=messages.append)
    assert any(says(m, "regenerating", "inst_00000", "checksum") for m in messages), messages
    read_every_instance(out)


def test_rerun_repairs_an_instance_whose_record_certifies_corrupt_bytes(tmp_path):
    """What the old race left behind: a broken file whose record and manifest carry its checksum."""
    out = tmp_path / "ds"
    generate_dataset(tiny_config(), out, progress=False, log=quiet)
    h5 = out / "instances" / "inst_00001.h5"
    data = bytearray(h5.read_bytes())
    mid = len(data) // 2
    data[mid:mid + 400] = bytes(400)  # zeros in the middle of compressed chunks
    h5.write_bytes(bytes(data))
    old_sha = json.loads((out / "instances" / "inst_00001.json").read_text())["sha256"]
    for certificate in (out / "instances" / "inst_00001.json", out / "manifest.json"):
        certificate.write_text(certificate.read_text().replace(old_sha, sha(h5)))
    load_dataset(out)  # the precondition: every checksum agrees ...
    with pytest.raises((OSError, DatasetError), match="filter returned failure during read"):
        read_every_instance(out)  # ... but the file does not read
    messages = []
    generate_dataset(tiny_config(), out, progress=False, log=messages.append)
    assert len(messages) == 1 and says(messages[0], "regenerating", "inst_00001", "does not read", "HDF5"), messages
    read_every_instance(out)


# ---------------------------------------------------------------- generate: arguments
def _cli(argv, capsys):
    rc = cli_main(argv)
    err = capsys.readouterr().err.strip()
    return rc, err


def test_generate_empty_out_is_refused_and_writes_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, err = _cli(["generate", "--out", "", "--quiet"], capsys)
    assert rc == 2 and err.startswith("error: --out is empty") and len(err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(UsageError, match="empty"):
        generate_dataset(tiny_config(), "", progress=False, log=quiet)
    assert list(tmp_path.iterdir()) == []


def test_negative_seed_is_refused_and_does_not_poison_the_folder(tmp_path, capsys):
    out = tmp_path / "ds"
    rc, err = _cli(["generate", "--out", str(out), "--seed", "-5", "--quiet"], capsys)
    assert rc == 2 and err.startswith("error: ") and says(err, "--seed", "-5"), err
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(UsageError, match="seed must be a non-negative integer, got -5"):
        generate_dataset(tiny_config(seed=-5), out, progress=False, log=quiet)
    assert list(tmp_path.iterdir()) == []
    generate_dataset(tiny_config(seed=0, n_instances=1), out, progress=False, log=quiet)  # the next valid run
    read_every_instance(out)


def test_missing_parent_folder_is_refused_by_the_cli(tmp_path, capsys):
    rc, err = _cli(["generate", "--out", str(tmp_path / "nope" / "ds"), "--quiet"], capsys)
    assert rc == 2 and err.startswith("error: ") and says(err, "--out", tmp_path / "nope" / "ds", "does not exist"), err
    assert list(tmp_path.iterdir()) == []


def test_read_only_parent_folder_is_refused_before_writing(tmp_path, monkeypatch):
    parent = tmp_path / "ro"
    parent.mkdir()
    parent.chmod(0o555)
    # As root, chmod does not stop writes; the generator asks the OS (os.access), so deny there too.
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == parent else real_access(p, mode, **kw))
    try:
        with pytest.raises(OutputPathError, match=f"{parent} is not a writable directory"):
            generate_dataset(tiny_config(), parent / "ds", progress=False, log=quiet)
        assert list(parent.iterdir()) == []
    finally:
        parent.chmod(0o755)


# ---------------------------------------------------------------- import
NV = 7


def _csv(path: Path, n=120, seed=0) -> Path:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    q = np.sin(t[:, None] * rng.uniform(1, 2, NV))
    tau = np.cos(t[:, None] * rng.uniform(1, 2, NV))
    names = ["t"] + [f"q{j}" for j in range(1, NV + 1)] + [f"tau{j}" for j in range(1, NV + 1)]
    lines = [",".join(names)] + [",".join(repr(float(v)) for v in r) for r in np.column_stack([t, q, tau])]
    path.write_text("\n".join(lines) + "\n")
    return path


COLUMNS = {"q": [f"q{j}" for j in range(1, NV + 1)], "tau_m": [f"tau{j}" for j in range(1, NV + 1)]}


def _import(log, out, **kw):
    return import_log(log, out, columns=COLUMNS, time="t", **kw)


def test_import_overwrite_refuses_a_folder_that_is_not_a_dataset(tmp_path):
    out = tmp_path / "results"
    out.mkdir()
    (out / "thesis.tex").write_text("years of work")
    with pytest.raises(OutputPathError) as err:
        _import(_csv(tmp_path / "log.csv"), out, overwrite=True)
    assert says(err.value, "refusing", out, "manifest"), err.value
    assert (out / "thesis.tex").read_text() == "years of work"
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == ["log.csv", "results"]


def test_import_overwrite_refuses_a_dataset_holding_a_user_file(tmp_path):
    log, out = _csv(tmp_path / "log.csv"), tmp_path / "ds"
    _import(log, out)
    (out / "notes.txt").write_text("mine")
    with pytest.raises(OutputPathError) as err:
        _import(log, out, overwrite=True)
    assert says(err.value, "refusing", out, "notes.txt", "manifest"), err.value
    assert (out / "notes.txt").read_text() == "mine"


def test_import_overwrite_replaces_its_own_dataset_and_spares_a_sibling_old(tmp_path):
    log, out = _csv(tmp_path / "log.csv"), tmp_path / "ds"
    _import(log, out)
    (tmp_path / "ds.old").mkdir()
    (tmp_path / "ds.old" / "keep.txt").write_text("the user's")
    _import(_csv(tmp_path / "log2.csv", seed=1), out, overwrite=True)
    assert (tmp_path / "ds.old" / "keep.txt").read_text() == "the user's"
    assert load_dataset(out).meta["import"]["sources"][0]["file"].endswith("log2.csv")
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == \
        ["ds", "ds.old", "log.csv", "log2.csv"]


def test_import_without_overwrite_spares_a_sibling_partial(tmp_path):
    (tmp_path / "ds.partial").mkdir()
    (tmp_path / "ds.partial" / "keep.txt").write_text("the user's")
    _import(_csv(tmp_path / "log.csv"), tmp_path / "ds")
    assert (tmp_path / "ds.partial" / "keep.txt").read_text() == "the user's"
    load_dataset(tmp_path / "ds")


def test_import_existing_output_without_overwrite_is_still_refused(tmp_path):
    out = tmp_path / "ds"
    out.mkdir()
    with pytest.raises(DatasetError, match="already exists"):
        _import(_csv(tmp_path / "log.csv"), out)


def test_generate_into_an_imported_dataset_is_refused(tmp_path):
    out = tmp_path / "ds"
    _import(_csv(tmp_path / "log.csv"), out)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    with pytest.raises(OutputPathError) as err:
        generate_dataset(tiny_config(), out, progress=False, log=quiet)
    assert says(err.value, "refusing", out, "manifest.json", "generator.json"), err.value
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    load_dataset(out)


# ---------------------------------------------------------------- bench
class Sentinel(Exception):
    """Raised by the dataset provider: the bench got past its output checks."""


def _no_data(scenario, profile):
    raise Sentinel(scenario)


@pytest.mark.parametrize("name", ["README.md", "results.csv"])
def test_bench_refuses_a_folder_with_a_users_file(tmp_path, name):
    from hybrid_dyn.bench.profiles import PROFILES
    from hybrid_dyn.bench.runner import run_bench

    out = tmp_path / "report"
    out.mkdir()
    (out / name).write_text("the user's own")
    with pytest.raises(OutputPathError) as err:
        run_bench(PROFILES.lookup("quick"), out, dataset_provider=_no_data, log=quiet)
    assert says(err.value, "refusing", out, name, "run.json"), err.value
    assert sorted(p.name for p in out.iterdir()) == [name] and (out / name).read_text() == "the user's own"


def test_bench_claims_a_new_folder_and_reuses_its_own(tmp_path):
    from hybrid_dyn.bench.profiles import PROFILES
    from hybrid_dyn.bench.runner import run_bench

    out = tmp_path / "report"
    for _ in range(2):  # new folder, then the folder it claimed (a killed run's)
        with pytest.raises(Sentinel):
            run_bench(PROFILES.lookup("quick"), out, dataset_provider=_no_data, log=quiet)
    meta = json.loads((out / "run.json").read_text())
    assert meta["profile"] == PROFILES.lookup("quick").to_dict()
    # the marker, and what a killed run's report needs: the rows requested and those found not to apply
    assert set(meta) == {"bench_report", "invocations", "profile", "requested", "skipped"}
    assert "mismatch-ext / joint_torque / rnea" in meta["requested"] and meta["skipped"] == []
    # the second run kept the first: both were interrupted (their time so far on record, none finished)
    assert [i["finished"] for i in meta["invocations"]] == [None, None]
    (out / "run.json").write_text('{"something": "else"}')
    with pytest.raises(OutputPathError, match="it is not a run.json of hybrid-dyn bench"):
        run_bench(PROFILES.lookup("quick"), out, dataset_provider=_no_data, log=quiet)


# ---------------------------------------------------------------- every command
def test_every_command_leaves_a_users_folder_alone(panda_log, tmp_path, capsys):
    """Ownership by proof: a folder holding a user's files that happen to carry the toolkit's
    file names (run.json with a 'profile' key, config.json, generator.json, manifest.json) is refused by
    bench, report, generate, train and import alike, and every file is left as it was."""
    from hybrid_dyn.cli import main as cli_main

    user = tmp_path / "mine"
    user.mkdir()
    files = {"run.json": json.dumps({"profile": "my-experiment", "lr": 0.01}), "README.md": "# notes\n",
             "results.csv": "epoch,loss\n1,0.5\n", "config.json": json.dumps({"lr": 0.01}),
             "generator.json": json.dumps({"profile": "x"}), "manifest.json": json.dumps({"format": "mine"})}
    for name, text in files.items():
        (user / name).write_text(text)
    spec = panda_log.parent / "logs" / "spec.toml"
    roots = ["--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]
    commands = {
        "bench": ["bench", "--data", str(panda_log), "--out", str(user), "--rows", "rnea", *roots],
        "report": ["report", str(user)],
        "generate": ["generate", "--scenario", "paper-noext", "--out", str(user), "--quiet"],
        "train": ["train", "--data", str(panda_log), "--preset", "seed-tau-mlp", "--out", str(user), "--max-epochs", "1"],
        "import": ["import", "--spec", str(spec), "--out", str(user), "--overwrite"],
    }
    seen = {}
    for name, argv in commands.items():
        capsys.readouterr()
        with time_limit(60, name):
            assert cli_main(argv) == 2, name
        err = capsys.readouterr().err
        assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, (name, err)
        assert {p.name: p.read_text() for p in user.iterdir()} == files, name
        seen[name] = err
    # Each names the folder as a user's, not as a dataset or model of another run.
    assert all("refusing to replace" in e and "not written by hybrid-dyn" in e for e in seen.values()), seen


# ---------------------------------------------------------------- predict --save
@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    import torch

    from hybrid_dyn import load_robot
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.learn import TrainConfig, train_model

    root = tmp_path_factory.mktemp("predict")
    data = make_synthetic_dataset(root / "ds", load_robot("panda"), n_instances=3, n_samples=60, seed=1)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        train_model(load_dataset(data), "seed-tip-11", root / "model",
                    TrainConfig(max_epochs=1, batch_size=64, progress=False, num_threads=1))
    finally:
        torch.set_num_threads(threads)
    return data, root / "model"


def test_predict_save_refuses_an_existing_file_and_overwrites_only_its_own(tiny_model, tmp_path, capsys):
    data, model = tiny_model
    target = tmp_path / "preds.h5"
    target.write_bytes(b"the user's file")
    argv = ["predict", "--model", str(model), "--data", str(data), "--split", "train", "--save", str(target)]
    rc, err = _cli(argv, capsys)
    assert rc == 2 and err.startswith("error: ") and says(err, "--save", target, "exists", "--overwrite"), err
    rc, err = _cli(argv + ["--overwrite"], capsys)
    assert rc == 2 and "it lacks the 'hybrid_dyn_predictions' attribute" in err
    assert target.read_bytes() == b"the user's file"
    target.unlink()
    assert _cli(argv, capsys)[0] == 0  # a new file
    assert _cli(argv + ["--overwrite"], capsys)[0] == 0  # its own file, replaced
    with h5py.File(target) as f:
        assert f.attrs["hybrid_dyn_predictions"] == 1 and len(f.keys()) > 0
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == ["preds.h5"]
