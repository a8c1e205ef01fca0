"""One name per concept: a generator *size* is not a bench *profile*, the training
recipes have names of their own, ``train`` takes ``--params`` and ``--max-epochs`` as ``bench`` and
TrainConfig say. Every old name still works, with a DeprecatedNameWarning naming the new one, and
nothing a cache or a report is keyed by moves: config hashes, fingerprints, run.json's profile."""
import json
import subprocess
import sys
import warnings

import pytest

from hybrid_dyn.bench.integrity import recorded_profile
from hybrid_dyn.bench.profiles import PROFILES
from hybrid_dyn.cli import build_parser
from hybrid_dyn.deprecation import DeprecatedNameWarning
from hybrid_dyn.learn.recipes import RECIPE_ALIASES, RECIPES, TrainConfig
from hybrid_dyn.sim.generator_config import SIZES, GeneratorConfig
from hybrid_dyn.sim.scenarios import scenario_config
from helpers.legacy_sensors import legacy

pytestmark = pytest.mark.system


@pytest.fixture
def no_deprecation():
    """Inside: a DeprecatedNameWarning is an error (the new names are silent)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecatedNameWarning)
        yield


# --------------------------------------------------------------------------- generator sizes
def test_a_generator_size_keeps_the_config_hash_it_had_as_a_profile(no_deprecation):
    # The hashes every cached dataset is stored under (also in test_seed_sim and test_contact_steps).
    assert scenario_config("paper-ext", size="default", **legacy("paper-ext")).config_hash() == "c6b41661db23d34c"
    assert scenario_config("mismatch-ext", "default", **legacy("mismatch-ext")).config_hash() == "59028684ff8f137c"
    cfg = scenario_config("seed-sim", size="paper")
    assert cfg.size == "paper" and cfg.to_dict()["profile"] == "paper" and "size" not in cfg.to_dict()
    assert list(cfg.to_dict())[:2] == ["scenario", "profile"]  # the stored key, in its place
    assert GeneratorConfig.from_dict(cfg.to_dict()) == cfg  # a manifest's config reads back
    assert SIZES == ("quick", "default", "paper")


def test_the_sizes_old_name_profile_is_gone_from_the_api_and_the_cli():
    """No release shipped ``profile`` for a generator size: the keyword, the field, the constant and the flag are
    refused like any unknown name (the stored key ``profile`` of to_dict stays: a file format)."""
    from hybrid_dyn.sim.generator_config import ConfigError

    with pytest.raises(ConfigError, match="profile"):
        scenario_config("paper-ext", profile="default")
    with pytest.raises(TypeError, match="profile"):
        GeneratorConfig(profile="paper")
    import hybrid_dyn.sim as sim
    import hybrid_dyn.sim.scenarios as scenarios

    for module in (sim, scenarios):
        assert not hasattr(module, "PROFILES")
    parser = build_parser()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecatedNameWarning)
        assert parser.parse_args(["generate", "--size", "paper", "--out", "x"]).size == "paper"
        assert parser.parse_args(["generate", "--out", "x"]).size == "quick"
    with pytest.raises(SystemExit):
        parser.parse_args(["generate", "--profile", "default", "--out", "x"])


def test_a_bench_profile_names_its_generator_size_and_run_json_keeps_the_key(no_deprecation):
    quick = PROFILES["quick"]
    assert quick.generator_size == "quick" and PROFILES["seed-sim"].generator_size == "paper"
    d = quick.to_dict()  # what run.json records, and report.py quotes as "generator size"
    assert d["generator_profile"] == "quick" and "generator_size" not in d
    assert list(d)[:3] == ["name", "scenarios", "generator_profile"]


# --------------------------------------------------------------------------- training recipes
def test_recipes_have_names_of_their_own_and_the_old_ones_warn(no_deprecation):
    assert set(RECIPES) == {"plateau", "long", "seed-study", "budget"}
    assert not set(RECIPES) & {"default", "seed"}  # a generator size, a bench profile; the random seed
    assert TrainConfig.recipe() == TrainConfig.recipe("plateau") == TrainConfig()
    for old, new in RECIPE_ALIASES.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecatedNameWarning)
            by_old = TrainConfig.recipe(old, seed=3)
        # the same fields, so the same fingerprint (the old recipe under its new name)
        assert by_old == TrainConfig.recipe(new, seed=3)
        assert by_old.fingerprint_fields() == TrainConfig.recipe(new, seed=3).fingerprint_fields()
    with pytest.warns(DeprecatedNameWarning, match="training recipe 'seed' is deprecated: use 'seed-study'"):
        assert TrainConfig.recipe("seed").lr_schedule == "none"


def test_a_run_json_of_an_old_recipe_name_is_the_same_profile(no_deprecation):
    """A report written with recipe "default" is recognised as the paper profile's own on a rerun
    (bench/runner.py compares run.json's profile with BenchProfile.to_dict())."""
    paper = PROFILES["paper"]
    assert paper.recipe == "plateau"
    recorded = {**paper.to_dict(), "recipe": "default"}  # as a run.json of before the rename holds it
    assert recorded != paper.to_dict() and recorded_profile(recorded) == paper.to_dict()
    assert recorded_profile({**recorded, "seed": 1}) != paper.to_dict()  # anything else still differs


# --------------------------------------------------------------------------- train flags
def _train_config(argv):
    from hybrid_dyn.learn.cli import _config

    return _config(build_parser().parse_args(["train", "--data", "d", "--preset", "seed-tip-1", "--out", "m"] + argv))


def test_train_takes_params_and_max_epochs(no_deprecation):
    cfg = _train_config(["--params", "franka_official", "--max-epochs", "7"])
    assert cfg.analytic_params == "franka_official" and cfg.max_epochs == 7
    assert _train_config([]).max_epochs == 200 and _train_config([]).analytic_params is None
    assert _train_config(["--recipe", "seed-study"]) == TrainConfig.recipe("seed-study", progress=True)


def test_an_old_recipe_name_warns_and_sets_the_same_fields():
    with pytest.warns(DeprecatedNameWarning, match="training recipe 'default' is deprecated: use 'plateau'"):
        cfg = _train_config(["--recipe", "default"])
    assert cfg == _train_config(["--recipe", "plateau"])


def test_the_command_line_prints_a_deprecation_as_one_line(tmp_path):
    """From a shell: the warning is one ``warning:`` line naming the new name, and the command goes on."""
    run = subprocess.run([sys.executable, "-m", "hybrid_dyn.cli", "train", "--data", str(tmp_path / "none"),
                          "--preset", "seed-tip-1", "--out", str(tmp_path / "m"), "--recipe", "default",
                          "--max-epochs", "0"], capture_output=True, text=True)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert lines[0] == "warning: training recipe 'default' is deprecated: use 'plateau'"
    assert lines[-1].startswith("error: TrainConfig.max_epochs (--max-epochs) must be an integer >= 1")


def test_bench_records_an_old_recipe_by_its_new_name(monkeypatch):
    import hybrid_dyn.bench.runner as runner
    from hybrid_dyn.cli import main

    seen = {}
    monkeypatch.setattr(runner, "run_bench", lambda profile, out, **kw: seen.setdefault("profile", profile) and [])
    with pytest.warns(DeprecatedNameWarning, match="training recipe 'seed' is deprecated: use 'seed-study'"):
        main(["bench", "--profile", "quick", "--recipe", "seed", "--out", "unused"])
    assert seen["profile"].recipe == "seed-study" and json.loads(json.dumps(seen["profile"].to_dict()))["recipe"] == \
        "seed-study"
