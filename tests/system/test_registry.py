"""The one registry mechanism: declarations, their checks, queries, the plugin hook on a miss, and help texts
whose lists are read from registries when printed."""
import argparse
from dataclasses import dataclass
from types import SimpleNamespace

import pytest

from hybrid_dyn import plugins
from hybrid_dyn.registry import Registry, help_listing


@dataclass(frozen=True)
class Thing:
    name: str
    colour: str = "red"


def _things(**kw) -> Registry:
    return Registry("thing", KeyError, LookupError, **kw)


def test_declarations_queries_and_refusals():
    things = _things(check=lambda t: None if t.colour != "plaid" else "plaid is no colour")
    for t in (Thing("a"), Thing("b", "blue"), Thing("c")):
        things.register(t)
    assert things.names() == ("a", "b", "c") and things.names(colour="red") == ("a", "c")
    assert [t.name for t in things.where(colour="blue")] == ["b"]
    with pytest.raises(KeyError, match="'a' is declared twice"):
        things.register(Thing("a"))
    with pytest.raises(KeyError, match="thing 'd': plaid is no colour"):
        things.register(Thing("d", "plaid"))
    assert "d" not in things


def test_register_all_declares_in_order_and_stops_at_a_refusal():
    things = _things().register_all([Thing("x"), Thing("y", "blue")])
    assert things.names() == ("x", "y")
    with pytest.raises(KeyError, match="'x' is declared twice"):
        things.register_all([Thing("z"), Thing("x")])
    assert things.names() == ("x", "y", "z")


def test_a_miss_loads_the_plugins_once_and_finds_what_they_declare(monkeypatch):
    things = _things()
    loads = []

    def entry_points(group):
        assert group == plugins.GROUP
        loads.append(group)
        return [SimpleNamespace(name="p", value="pkg.mod", load=lambda: things.register(Thing("from-plugin")))]

    monkeypatch.setattr(plugins.importlib.metadata, "entry_points", entry_points)
    monkeypatch.setattr(plugins, "LOADED", {})
    monkeypatch.setitem(plugins._state, "scanned", False)
    assert things.missing(["x", "from-plugin"]) == ["x"]  # not declared until the check loaded the plugin
    assert things.lookup("from-plugin").name == "from-plugin"
    with pytest.raises(LookupError, match="unknown thing 'nope'; known: from-plugin"):
        things.lookup("nope")
    assert loads == [plugins.GROUP] and plugins.LOADED == {"p": "pkg.mod"}  # scanned once, not per miss


def test_help_lists_are_read_when_printed():
    things = _things()
    parser = argparse.ArgumentParser(prog="x", formatter_class=help_listing(things=lambda: things))
    parser.add_argument("--thing", help="one of {things}")
    things.register(Thing("late"))  # declared after the parser was built
    things.register(Thing("100%"))
    assert "one of late, 100%" in " ".join(parser.format_help().split())


@pytest.mark.parametrize("listing", [list, len, lambda r: r.names(), lambda r: r.where(), lambda r: list(r.values()),
                                     lambda r: list(r.items()), lambda r: list(r.keys())])
def test_every_listing_loads_the_plugins_first(monkeypatch, listing):
    """A listing (a --help, a choice, a contract test's parameters) shows a plugin's declarations, as a lookup finds them."""
    things = _things()

    def entry_points(group):
        return [SimpleNamespace(name="p", value="pkg.mod", load=lambda: things.register(Thing("from-plugin")))]

    monkeypatch.setattr(plugins.importlib.metadata, "entry_points", entry_points)
    monkeypatch.setattr(plugins, "LOADED", {})
    monkeypatch.setitem(plugins._state, "scanned", False)
    assert "from-plugin" not in dict.keys(things)  # a plain dict read loads nothing
    listing(things)
    assert "from-plugin" in dict.keys(things) and plugins.LOADED == {"p": "pkg.mod"}


def test_a_listing_while_the_toolkit_imports_waits_for_the_import(monkeypatch):
    """A catalogue that reads its registry at import time must not hand a plugin half-built modules."""
    import sys

    from hybrid_dyn import registry

    monkeypatch.setattr(plugins, "load_plugins", lambda: pytest.fail("plugins loaded during the toolkit's import"))
    monkeypatch.setitem(plugins._state, "scanned", False)
    importing = SimpleNamespace(__spec__=SimpleNamespace(_initializing=True))
    monkeypatch.setitem(sys.modules, "hybrid_dyn.toy_catalogue", importing)
    list(_things())
    assert registry._importing_the_toolkit()
