"""``hybrid-dyn``: a thin command-line shell over the library.

Each area registers its own subcommands through a ``register(subparsers)``
function in its ``cli.py``; this file only wires them together, after the
installed plugins have declared theirs (``plugins.py``), so that every list
in the help and every choice knows them.
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

# Modules that contribute subcommands; each has register(subparsers).
SUBCOMMAND_MODULES = [
    "hybrid_dyn.analytic.cli",
    "hybrid_dyn.sim.cli",
    "hybrid_dyn.data.logs.cli",
    "hybrid_dyn.estimator.replay_cli",
    "hybrid_dyn.bench.cli",
    "hybrid_dyn.identify.cli",
    "hybrid_dyn.learn.cli",
]


def build_parser() -> argparse.ArgumentParser:
    load_plugins()  # a plugin's method, row or robot is in the help and the choices built below
    parser = argparse.ArgumentParser(prog="hybrid-dyn", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for mod in SUBCOMMAND_MODULES:
        importlib.import_module(mod).register(sub)
    return parser


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
        return _run(build_parser().parse_args(argv))
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
