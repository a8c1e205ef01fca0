"""Old names that still work, and say so: one warning class and the helpers that raise it.

Only names a file on disk may still hold are kept as aliases (a registry's ``alias``: the estimators'
spellings in model files of format 1-2, the recipe names in committed run.json files), never silently:
each raises a :class:`DeprecatedNameWarning` that names what to write instead.

The class derives from ``FutureWarning``, not ``DeprecationWarning``, so that Python shows it by
default: the old names are typed by users of the CLI and read from their files, and
``DeprecationWarning`` is hidden outside ``__main__``.
"""
from __future__ import annotations

import warnings


class DeprecatedNameWarning(FutureWarning):
    """An old name (a flag, keyword, field, recipe or estimator spelling) was used; the message says the new one."""


def warn_renamed(what: str, old: str, new: str, stacklevel: int = 2, why: str = "") -> None:
    """Warn that ``old`` (a ``what``: "flag", "training recipe", "GeneratorConfig field", ...) is now ``new``."""
    message = f"{what} {old!r} is deprecated: use {new!r}" + (f" ({why})" if why else "")
    warnings.warn(message, DeprecatedNameWarning, stacklevel=stacklevel + 1)
