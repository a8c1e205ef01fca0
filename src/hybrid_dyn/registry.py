"""The one registry mechanism: every named thing of the toolkit is declared once, in a :class:`Registry`.

Estimator methods, their bandwidth parameters, network kinds, presets, bench rows and families,
scenarios, robots, profiles, studies and real-log sets each have one registry. A declaration is a
(frozen) dataclass with a ``name``: its fields are its metadata (what it reads, its family, its
parameters and their defaults), so that every list, tuple and table a consumer needs is derived from
the registry instead of being kept by hand beside it.

A registry is a ``dict`` (name -> declaration), so ``keys()`` is a live view of the names, in
declaration order. What it adds:
- refusals: a name declared twice, and an unknown name looked up (naming the known ones);
- aliases: an old name that still resolves, with a :class:`~hybrid_dyn.deprecation.DeprecatedNameWarning`
  naming the new one (``lookup``, ``canonical``);
- listeners: a consumer that derives something per declaration (the bench's rows of a method) hears of
  a declaration made after it was built, and of its removal.
"""
from __future__ import annotations

from typing import Callable

from .deprecation import warn_renamed


class Registry(dict):
    """Declarations of one sort by their ``name``; ``what`` names the sort in the errors.

    twice: the exception for a name declared twice; unknown: for an unknown name looked up.
    """

    def __init__(self, what: str, twice: type[Exception], unknown: type[Exception] | None = None):
        super().__init__()
        self.what, self._twice, self._unknown = what, twice, unknown or twice
        self.aliases: dict[str, tuple[str, str]] = {}  # old name -> (new name, why it changed)
        self._listeners: list[tuple[Callable, Callable | None]] = []

    def register(self, item):
        """Declare ``item`` (anything with a ``name``): from now on every consumer of the registry knows it."""
        if item.name in self or item.name in self.aliases:
            raise self._twice(f"{self.what} {item.name!r} is declared twice")
        self[item.name] = item
        for on_register, _ in list(self._listeners):
            on_register(item)
        return item

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
        """The declaration of ``name`` (or of the name an alias stands for), or the error naming the known ones."""
        name = self.canonical(name, stacklevel=3)
        if name not in self:
            raise self._unknown(f"unknown {self.what} {name!r}; known: {', '.join(self)}")
        return self[name]

    def listen(self, on_register: Callable, on_unregister: Callable | None = None) -> None:
        """Call ``on_register(item)`` for every declaration from now on (and ``on_unregister`` on removal).
        The declarations made before are the listener's to read from the registry itself."""
        self._listeners.append((on_register, on_unregister))

    def where(self, **fields) -> list:
        """The declarations whose metadata has every ``field=value`` given, in declaration order."""
        return [item for item in self.values() if all(getattr(item, k, None) == v for k, v in fields.items())]
