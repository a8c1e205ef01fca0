"""The toolkit's own error classes share one base, so that the CLI can tell a user's
mistake (a ``HybridDynError``: printed as one line, exit 2) from a bug in the toolkit
(any other exception: its traceback is shown).

Most subclasses also derive from ``ValueError`` for callers that already catch that.
"""
from __future__ import annotations


class HybridDynError(Exception):
    """Base of every error the toolkit raises on purpose about its input, files or arguments."""


class UsageError(HybridDynError, ValueError):
    """A command-line or API argument is out of range or inconsistent (named in the message)."""


class OutputPathError(HybridDynError, ValueError):
    """An output path holds something the toolkit did not write, or is locked by another run."""


class MissingDependencyError(HybridDynError, RuntimeError):
    """An optional dependency that the chosen option needs is not installed (the message says what to install)."""
