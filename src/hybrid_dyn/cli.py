"""``hybrid-dyn``: a thin command-line shell over the library.

Each area registers its own subcommands through a ``register(subparsers)``
function in its ``cli.py``; this file only wires them together.
"""
from __future__ import annotations

import argparse
import importlib
import sys

# Modules that contribute subcommands; each has register(subparsers).
SUBCOMMAND_MODULES = [
    "hybrid_dyn.analytic.cli",
    "hybrid_dyn.sim.cli",
    "hybrid_dyn.data.import_cli",
    "hybrid_dyn.bench.cli",
    "hybrid_dyn.identify.cli",
    "hybrid_dyn.learn.cli",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hybrid-dyn", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for mod in SUBCOMMAND_MODULES:
        importlib.import_module(mod).register(sub)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("\ninterrupted; finished work is kept and a rerun resumes", file=sys.stderr)
        return 130
    except ValueError as err:  # our input errors are ValueError subclasses: print them plainly
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
