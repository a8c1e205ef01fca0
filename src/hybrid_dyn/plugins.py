"""Installed plugins: packages that declare methods, network kinds, rows, families or robots of their own.

A plugin is an installed distribution with an entry point in the group ``hybrid_dyn.plugins``
(``pyproject.toml``: ``[project.entry-points."hybrid_dyn.plugins"] my-name = "my_package.module"``).
Its module is imported once per process, and its import registers what it brings through the public
registries (``METHODS.register(...)``, ``ROWS.register(...)``, ...). Plugins are loaded by the CLI
before it builds its help, by :meth:`registry.Registry.lookup` the first time a name is missing, and by the
first listing of any registry (iteration, ``where``, ``names``), so that a plugin's names are everywhere.
"""
from __future__ import annotations

import importlib.metadata
import warnings

GROUP = "hybrid_dyn.plugins"
LOADED: dict[str, str] = {}  # entry-point name -> the module it imported (or the error that stopped it)
_state = {"scanned": False}


def scanned() -> bool:
    """Whether this process has looked for its plugins already (:func:`load_plugins` ran)."""
    return _state["scanned"]


def load_plugins() -> bool:
    """Import every plugin of :data:`GROUP` not imported yet; whether this call imported any.

    A plugin that fails to import is reported in one warning naming it and left out (the toolkit's own
    commands still run); it is not tried again in this process."""
    if _state["scanned"]:
        return False
    _state["scanned"] = True  # first: a plugin's own lookups (while it imports) must not load it again
    found = False
    for entry in importlib.metadata.entry_points(group=GROUP):
        if entry.name in LOADED:
            continue
        try:
            entry.load()
            LOADED[entry.name] = entry.value
            found = True
        except Exception as err:  # any error of a foreign package: name it, keep the toolkit usable
            LOADED[entry.name] = f"failed: {err}"
            warnings.warn(f"hybrid_dyn plugin {entry.name!r} ({entry.value}) failed to load: "
                          f"{type(err).__name__}: {err}", RuntimeWarning, stacklevel=2)
    return found
