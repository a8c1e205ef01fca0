"""The one registry mechanism: every named thing of the toolkit is declared once, in a :class:`Registry`.

Each sort of declaration (estimator methods, network kinds, presets, bench rows, families, profiles,
studies, scenarios, robots, ...) has one module-level plural name holding its registry, completed by
one catalogue module. A declaration is a frozen dataclass with a ``name``; consumers read the registry
with its methods only: ``lookup``, ``register``, ``where``, ``names``, iteration. Aliases, listeners
and the plugin hook (a miss or a listing loads the installed plugins): ``docs/extending.md``.
"""
from __future__ import annotations

import argparse
import sys
from typing import Callable, Iterable

from .deprecation import warn_renamed


class Registry(dict):
    """Declarations of one sort by their ``name``; ``what`` names the sort in the errors.

    twice: the exception for a name declared twice; unknown: for an unknown name looked up;
    check(item) -> str | None: an optional rule every declaration must pass (the reason it is refused).
    """

    def __init__(self, what: str, twice: type[Exception], unknown: type[Exception] | None = None,
                 check: Callable | None = None):
        super().__init__()
        self.what, self._twice, self._unknown, self._check = what, twice, unknown or twice, check
        self.aliases: dict[str, tuple[str, str]] = {}  # old name -> (new name, why it changed)
        self._listeners: list[tuple[Callable, Callable | None]] = []

    def register(self, item):
        """Declare ``item`` (anything with a ``name``): from now on every consumer of the registry knows it."""
        if item.name in self or item.name in self.aliases:
            raise self._twice(f"{self.what} {item.name!r} is declared twice")
        reason = self._check(item) if self._check is not None else None
        if reason:
            raise self._twice(f"{self.what} {item.name!r}: {reason}")
        self[item.name] = item
        for on_register, _ in list(self._listeners):
            on_register(item)
        return item

    def register_all(self, items) -> "Registry":
        """Declare every item of ``items`` in order (a catalogue read from a file); returns the registry."""
        for item in items:
            self.register(item)
        return self

    def unregister(self, name: str) -> None:
        """Remove a declaration (a test's toy), and tell the listeners."""
        item = self.pop(name)
        for _, on_unregister in list(self._listeners):
            if on_unregister is not None:
                on_unregister(item)

    def alias(self, old: str, new: str, why: str = "") -> None:
        """Keep ``old`` as a name of ``new`` that still resolves, with a deprecation warning."""
        if old in self or old in self.aliases:
            raise self._twice(f"{self.what} {old!r} is declared twice (as an alias of {new!r})")
        self.aliases[old] = (new, why)

    def canonical(self, name: str, stacklevel: int = 2) -> str:
        """``name`` itself, or the name an alias stands for (warning that it is deprecated)."""
        if name in self.aliases:
            new, why = self.aliases[name]
            warn_renamed(self.what, name, new, stacklevel=stacklevel + 1, why=why)
            return new
        return name

    def lookup(self, name: str):
        """The declaration of ``name`` (or of the name an alias stands for), or the error naming the known ones.

        A name not declared loads the installed plugins first (``plugins.load_plugins``, once per process), as
        a listing does: a plugin's declaration is found by the first lookup that asks for it."""
        name = self.canonical(name, stacklevel=3)
        if self.missing([name]):  # after the plugins not imported yet, which may declare it
            raise self._unknown(f"unknown {self.what} {name!r}; known: {', '.join(self)}")
        return self[name]

    def missing(self, names) -> list:
        """The ``names`` not declared (after loading the installed plugins, as :meth:`lookup` does), in order."""
        if any(n not in self for n in names):
            _load_plugins()
        return [n for n in names if n not in self]

    def listen(self, on_register: Callable, on_unregister: Callable | None = None) -> None:
        """Call ``on_register(item)`` for every declaration from now on (and ``on_unregister`` on removal).
        The declarations made before are the listener's to read from the registry itself."""
        self._listeners.append((on_register, on_unregister))

    def where(self, **fields) -> list:
        """The declarations whose metadata has every ``field=value`` given, in declaration order."""
        return [item for item in self.values() if all(getattr(item, k, None) == v for k, v in fields.items())]

    def names(self, **fields) -> tuple:
        """The names of the declarations :meth:`where` gives, in declaration order (every name with no field)."""
        return tuple(item.name for item in self.where(**fields))


def _load_plugins() -> None:
    """The installed plugins, for a listing; not while a toolkit module is still being imported: a catalogue
    that reads its registry at import (``bench/analytic_rows.py``) would hand a plugin half-built modules. The
    listing after the import loads them."""
    from .plugins import load_plugins, scanned  # here, not at the top: plugins.py may one day read a registry

    if scanned() or _importing_the_toolkit():
        return
    load_plugins()


def _importing_the_toolkit() -> bool:
    # importlib marks a module's spec ``_initializing`` while its code runs.
    return any(getattr(getattr(m, "__spec__", None), "_initializing", False)
               for name, m in list(sys.modules.items()) if name.partition(".")[0] == "hybrid_dyn")


def help_listing(**sources: Callable[[], Iterable[str]]) -> type[argparse.HelpFormatter]:
    """An argparse ``formatter_class`` whose help texts may name ``{key}``: the names ``sources[key]()`` gives
    (a registry's, a plugin's included), read when the help is printed, so that no list is kept by hand and
    a command that prints no help imports nothing for it."""

    class Names(dict):
        def __missing__(self, key):  # argparse expands %(...)s after us: a name's own % is kept literal
            return ", ".join(sources[key]()).replace("%", "%%")

    class HelpWithNames(argparse.HelpFormatter):
        def _get_help_string(self, action):
            return (action.help or "").format_map(Names())

    return HelpWithNames


def _listing(name: str):
    """Registry's ``name`` (a way of reading the whole registry): the installed plugins' declarations loaded first
    (once per process), so that --help, choices and contract tests see what a lookup would find."""
    def read(self):
        _load_plugins()
        return getattr(dict, name)(self)

    read.__name__ = read.__qualname__ = name
    return read


for _name in ("__iter__", "keys", "values", "items", "__len__"):
    setattr(Registry, _name, _listing(_name))
