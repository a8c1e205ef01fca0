"""``hybrid-dyn``: a thin command-line shell over the library.

Each area registers its own subcommands through a ``register(subparsers)``
function in its ``cli.py``; this file only wires them together, after the
installed plugins have declared theirs (``plugins.py``), so that every list
in the help and every choice knows them. Only the area of the command given
is imported (:data:`COMMANDS`).
"""
from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
import warnings

from .deprecation import DeprecatedNameWarning
from .errors import HybridDynError
from .plugins import load_plugins

# Each command: the module whose ``register(subparsers)`` builds it, and its line in ``hybrid-dyn --help`` (the
# one place it is written: ``add_parser(name)`` takes it from here). Only the module of the command given is
# imported, so that ``hybrid-dyn --help`` and ``hybrid-dyn import --help`` do not load PyTorch for a list.
COMMANDS = {
    "robots": ("hybrid_dyn.analytic.cli", "list the robot descriptions and their parameter sets"),
    "analytic-demo": ("hybrid_dyn.analytic.cli", "the analytic tip-force baselines on a small synthetic set"),
    "generate": ("hybrid_dyn.sim.cli", "simulate a dataset of a named scenario (DART, 1 kHz)"),
    "import": ("hybrid_dyn.data.logs.cli",
               "import a robot log (CSV, npz, .mat, Parquet, ROS bag) described by a TOML spec"),
    "estimate": ("hybrid_dyn.estimator.replay_cli",
                 "replay a recorded log (a ROS bag, CSV, ...) through the streaming tip-force estimator; "
                 "write /tip_force to an MCAP bag or a CSV"),
    "calibrate": ("hybrid_dyn.estimator.replay_cli",
                  "calibrate the estimator's error bars, bandwidth and max_sigma on a free-motion log of your arm "
                  "for a torque model (its validation part)"),
    "bench": ("hybrid_dyn.bench.cli", "every model family on the same data; writes results.csv, tables, figures"),
    "study": ("hybrid_dyn.bench.cli",
              "a bench profile rerun with overrides declared as data (e.g. data-scaling: the learned "
              "rows on fewer training instances), summarised against the profile's report"),
    "compare": ("hybrid_dyn.bench.cli",
                "two bench reports side by side: each learned row against its own report's best analytic "
                "row (reports on different data test on different samples)"),
    "report": ("hybrid_dyn.bench.cli", "redraw a bench report's tables and figures from its files (no training)"),
    "identify": ("hybrid_dyn.identify.cli", "identify inertial and friction parameters from a dataset"),
    "excitation": ("hybrid_dyn.identify.cli",
                   "design an excitation trajectory and record identification data on the plant"),
    "presets": ("hybrid_dyn.learn.cli", "list the learned-model presets"),
    "train": ("hybrid_dyn.learn.cli", "train a learned model on a dataset"),
    "predict": ("hybrid_dyn.learn.cli", "evaluate a trained model on a dataset split"),
    "tune": ("hybrid_dyn.learn.cli", "hyperparameter search with Optuna (the reference study's search space)"),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``hybrid-dyn`` parser. command: the command about to run (only its module is imported; the other
    commands are listed by their line of :data:`COMMANDS`), "" for none (``hybrid-dyn --help``), None for
    every command built in full (a test's, a documentation's)."""
    load_plugins()  # a plugin's method, row or robot is in the help and the choices built below
    parser = argparse.ArgumentParser(prog="hybrid-dyn", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    modules = dict.fromkeys(m for name, (m, _) in COMMANDS.items() if command is None or name == command)
    for mod in modules:
        importlib.import_module(mod).register(_Commands(sub))
    for name, (_, line) in COMMANDS.items():
        if name not in sub.choices:  # not built: listed, and refused by name if given without its module
            sub.add_parser(name, help=line, add_help=False)
    return parser


class _Commands:
    """The subparsers a module's ``register`` adds its commands to: each gets its line of :data:`COMMANDS`."""

    def __init__(self, sub):
        self._sub = sub

    def add_parser(self, name: str, **kwargs) -> argparse.ArgumentParser:
        return self._sub.add_parser(name, help=COMMANDS[name][1], **kwargs)


def _command(argv) -> str:
    """The command ``argv`` names: its first word that is not an option ("" when none is)."""
    words = [a for a in (sys.argv[1:] if argv is None else argv) if not a.startswith("-")]
    return words[0] if words and words[0] in COMMANDS else ""


class Terminated(KeyboardInterrupt):
    """SIGTERM (a scheduler's or ``kill``'s stop): unwinds like Ctrl-C, so workers are stopped and
    finished work is kept."""


def _on_sigterm(signum, frame):
    raise Terminated()


def main(argv=None) -> int:
    """Run one command. Exit status: 0 done; 2 a user error (a ``HybridDynError``: one line, no
    traceback); 130/143 interrupted by SIGINT/SIGTERM; any other exception is a bug in the toolkit
    and propagates with its traceback (exit 1)."""
    formatwarning = warnings.formatwarning
    warnings.formatwarning = _one_line_deprecation(formatwarning)  # an old recipe or estimator name, one line
    try:
        return _run(build_parser(_command(argv)).parse_args(argv))
    finally:
        warnings.formatwarning = formatwarning


def _one_line_deprecation(formatwarning):
    """A renamed name is the user's to fix, not a place in the toolkit: ``warning: <message>``."""

    def one_line(message, category, filename, lineno, line=None):
        if issubclass(category, DeprecatedNameWarning):
            return f"warning: {message}\n"
        return formatwarning(message, category, filename, lineno, line)

    return one_line


def _run(args) -> int:
    handle_term = _main_thread()
    previous = signal.signal(signal.SIGTERM, _on_sigterm) if handle_term else None
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt as err:
        print("\ninterrupted; finished work is kept and a rerun resumes", file=sys.stderr)
        return 143 if isinstance(err, Terminated) else 130
    except HybridDynError as err:  # the toolkit's own errors name the problem: print them plainly
        print(f"error: {err}", file=sys.stderr)
        return 2
    finally:
        if handle_term:  # None: a handler not set from Python; the default is what it was
            signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def _main_thread() -> bool:
    # signal.signal works only in the main thread (main() may be called from a test's thread).
    return threading.current_thread() is threading.main_thread()


if __name__ == "__main__":
    sys.exit(main())
