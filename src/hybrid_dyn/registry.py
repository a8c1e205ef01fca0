"""A registry of named declarations (scenarios, network kinds): one entry per name, in declaration order.

A ``dict`` (name -> declaration), so its ``keys()`` is a live view of the names; what it adds is
the refusals: a name declared twice, and an unknown name looked up (naming the known ones).
"""
from __future__ import annotations


class Registry(dict):
    """Declarations of one sort by their ``name``; ``what`` names the sort in the errors.

    twice: the exception for a name declared twice; unknown: for an unknown name looked up.
    """

    def __init__(self, what: str, twice: type[Exception], unknown: type[Exception] | None = None):
        super().__init__()
        self.what, self._twice, self._unknown = what, twice, unknown or twice

    def register(self, item):
        """Declare ``item`` (anything with a ``name``): from now on every consumer of the registry knows it."""
        if item.name in self:
            raise self._twice(f"{self.what} {item.name!r} is declared twice")
        self[item.name] = item
        return item

    def unregister(self, name: str) -> None:
        """Remove a declaration (a test's toy)."""
        self.pop(name)

    def lookup(self, name: str):
        """The declaration of ``name``, or the error naming the known ones."""
        if name not in self:
            raise self._unknown(f"unknown {self.what} {name!r}; known: {', '.join(self)}")
        return self[name]
