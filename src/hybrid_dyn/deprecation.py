"""Old names that still work, and say so: one warning class and the helpers that raise it.

Only names a file on disk may still hold are kept as aliases (a registry's ``alias``: the estimators'
spellings in model files of format 1-2, the recipe names in committed run.json files), never silently:
each raises a :class:`DeprecatedNameWarning` that names what to write instead.

The class derives from ``FutureWarning``, not ``DeprecationWarning``, so that Python shows it by
default: the old names are typed by users of the CLI and read from their files, and
``DeprecationWarning`` is hidden outside ``__main__``.
"""
from __future__ import annotations

import argparse
import functools
import warnings


class DeprecatedNameWarning(FutureWarning):
    """An old name (a flag, keyword, field, recipe or estimator spelling) was used; the message says the new one."""


def warn_renamed(what: str, old: str, new: str, stacklevel: int = 2, why: str = "") -> None:
    """Warn that ``old`` (a ``what``: "flag", "training recipe", "GeneratorConfig field", ...) is now ``new``."""
    message = f"{what} {old!r} is deprecated: use {new!r}" + (f" ({why})" if why else "")
    warnings.warn(message, DeprecatedNameWarning, stacklevel=stacklevel + 1)


def renamed_keyword(old: str, new: str, why: str = ""):
    """Decorator: the function takes keyword ``old`` as ``new`` (with a warning); both at once is an error."""

    def wrap(func):
        @functools.wraps(func)
        def call(*args, **kwargs):
            if old in kwargs:
                if new in kwargs:
                    raise TypeError(f"{func.__name__}() got both {new!r} and its old name {old!r}")
                warn_renamed(f"{func.__name__}() keyword", old, new, stacklevel=2, why=why)
                kwargs[new] = kwargs.pop(old)
            return func(*args, **kwargs)

        return call

    return wrap


def renamed_field(old: str, new: str, why: str = ""):
    """Class decorator for a dataclass whose field ``new`` was called ``old``: the constructor takes
    ``old=`` and the instance reads ``.old``, each with a warning. Apply it above ``@dataclass``."""

    def wrap(cls):
        init = cls.__init__

        @functools.wraps(init)
        def __init__(self, *args, **kwargs):
            if old in kwargs:
                if new in kwargs:
                    raise TypeError(f"{cls.__name__}() got both {new!r} and its old name {old!r}")
                warn_renamed(f"{cls.__name__} field", old, new, stacklevel=2, why=why)
                kwargs[new] = kwargs.pop(old)
            init(self, *args, **kwargs)

        def read_old(self):
            warn_renamed(f"{cls.__name__} field", old, new, stacklevel=2, why=why)
            return getattr(self, new)

        cls.__init__ = __init__
        setattr(cls, old, property(read_old, doc=f"Deprecated: {new}."))
        return cls

    return wrap


class DeprecatedFlag(argparse.Action):
    """An argparse flag kept as an alias of a renamed one: it stores into the new flag's ``dest`` and warns.

    ``p.add_argument("--epochs", dest="max_epochs", type=int, action=DeprecatedFlag, new="--max-epochs",
    help=argparse.SUPPRESS)``."""

    def __init__(self, option_strings, dest, new: str, **kwargs):
        self.new = new
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        warn_renamed("flag", option_string, self.new, stacklevel=1)
        setattr(namespace, self.dest, values)


def module_aliases(module_name: str, aliases: dict, namespace: dict, why: str = ""):
    """A module ``__getattr__`` that serves old module-level names (``{old: new}``) with a warning."""

    def __getattr__(name):
        if name in aliases:
            warn_renamed("name", f"{module_name}.{name}", f"{module_name}.{aliases[name]}", stacklevel=2, why=why)
            return namespace[aliases[name]]
        raise AttributeError(f"module {module_name!r} has no attribute {name!r}")

    return __getattr__
