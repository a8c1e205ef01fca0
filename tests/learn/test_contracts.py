"""What every declared network kind and preset must hold: parametrized over the registries, so that a new
declaration (the toolkit's, or a plugin's) is tested without an edit here."""
import numpy as np
import optuna
import pytest
import torch

from hybrid_dyn.bench.catalog import ROWS
from hybrid_dyn.bench.families import FAMILIES
from hybrid_dyn.learn.fastpath import FastNet
from hybrid_dyn.learn.kinds import NETWORK_KINDS, build_net, preset_problems
from hybrid_dyn.learn.presets import PRESETS, Preset
from hybrid_dyn.learn.tune import suggest_preset

WINDOW, N_IN, N_OUT = 10, 5, 3


@pytest.mark.parametrize("name", [k.name for k in NETWORK_KINDS.values() if k.is_net])
def test_a_net_kinds_float64_fast_path_equals_its_torch_network(name):
    """The single-window path the streaming estimator runs against the kind's own torch module in float64."""
    torch.manual_seed(0)
    net = build_net(name, N_IN, N_OUT, WINDOW, front_units=(6, 4), fc_layers=2, fc_units=8,
                    activation="tanh").double().eval()
    with torch.no_grad():  # non-zero biases, so that every term is exercised
        for p in net.parameters():
            p.add_(0.3 * torch.randn_like(p))
    x = np.random.default_rng(1).normal(scale=2.0, size=(WINDOW, N_IN))
    with torch.no_grad():
        ref = net(torch.from_numpy(x)[None])[0].numpy()
    np.testing.assert_allclose(FastNet(net)(x), ref, rtol=0, atol=1e-12)


def _base(kind) -> Preset:
    """A preset of ``kind``: a declared one, or the least the kind's rules allow."""
    declared = PRESETS.where(kind=kind.name)
    if declared:
        return declared[0]
    return Preset(f"toy-{kind.name}", kind.name, ("q", "qd", "qdd"), ("tau_m",), window=5 if kind.sequence else 1,
                  front_units=(8,) if kind.needs_front else ())


@pytest.mark.parametrize("name", list(NETWORK_KINDS))
def test_a_kinds_search_draws_presets_its_rules_accept(name):
    kind = NETWORK_KINDS[name]
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    for _ in range(5):
        tuned = suggest_preset(study.ask(), _base(kind))
        assert tuned.kind == name and preset_problems(tuned) == []


@pytest.mark.parametrize("name", list(PRESETS))
def test_a_preset_is_a_row_of_its_family_and_reads_back_from_its_file_form(name):
    p = PRESETS[name]
    assert p.family in FAMILIES and ROWS[name].family == p.family and ROWS[name].trains
    assert preset_problems(p) == []
    back = Preset.from_dict(p.to_dict())
    assert back == p and back.fingerprint_dict() == p.fingerprint_dict()
    assert "family" not in p.to_dict()  # metadata of the declaration, not of the model file
