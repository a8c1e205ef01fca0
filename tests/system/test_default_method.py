"""One default tip-force method: the API, ``hybrid-dyn estimate``, the example and the docs all name
``analytic.methods.DEFAULT_METHOD`` (there were four defaults for one method)."""
from __future__ import annotations

import argparse
import importlib.util
import inspect

import pytest

from hybrid_dyn.analytic.methods import DEFAULT_METHOD, TIP_FORCE_METHODS

from helpers import REPO


class _Parsed(Exception):
    """Raised in place of running the example once its arguments are parsed."""


def test_the_default_is_a_declared_method():
    assert DEFAULT_METHOD in TIP_FORCE_METHODS.names()


def test_the_api_defaults_to_it():
    from hybrid_dyn.estimator import TipForceEstimator
    from hybrid_dyn.estimator.replay import estimate_to, replay_log

    for fn in (TipForceEstimator.analytic, replay_log, estimate_to):
        assert inspect.signature(fn).parameters["method"].default == DEFAULT_METHOD, fn.__qualname__


def test_an_estimator_built_without_a_method_runs_it(panda):
    from hybrid_dyn.estimator import TipForceEstimator

    assert TipForceEstimator.analytic(panda, call_hz=1000.0).method == DEFAULT_METHOD


def test_the_estimate_command_defaults_to_it():
    from hybrid_dyn.cli import build_parser

    args = build_parser().parse_args(["estimate", "log.toml", "--out", "tip.csv"])
    assert args.method == DEFAULT_METHOD


def test_the_control_loop_example_defaults_to_it(monkeypatch):
    spec = importlib.util.spec_from_file_location("control_loop", REPO / "examples" / "control_loop.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    parse = argparse.ArgumentParser.parse_args

    def parse_then_stop(self, args=None, namespace=None):
        raise _Parsed(parse(self, args, namespace))

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", parse_then_stop)
    with pytest.raises(_Parsed) as parsed:
        example.main([])
    assert parsed.value.args[0].method == DEFAULT_METHOD


@pytest.mark.parametrize("page, says", [("README.md", "The default method is `{}`"),
                                        ("docs/estimator.md", "The default is `{}`")])
def test_the_docs_name_it(page, says):
    assert says.format(DEFAULT_METHOD) in (REPO / page).read_text()
