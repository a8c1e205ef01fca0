"""The package's layers: each module imports only from its own layer or those below, and no import circles.

The layers, from the bottom up, as `docs/layout.md` lists them. Every ``import`` of a
``hybrid_dyn`` module counts, those inside functions too (a lazy import still ties the two modules).
"""
from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"
PACKAGE = SRC / "hybrid_dyn"

# Bottom up; the shared top-level modules (registry, errors, deprecation, outputs, timing) are layer 0.
LAYERS = ["", "resources", "description", "data", "analytic", "sim", "identify", "learn", "estimator", "bench", "cli"]


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _layer(module: str) -> int:
    parts = module.split(".")
    if len(parts) == 1:  # the package's face, hybrid_dyn/__init__.py: re-exports, above nothing in particular
        return len(LAYERS)
    sub = parts[1]
    if sub in LAYERS:
        return LAYERS.index(sub)
    return 0  # a shared top-level module (registry.py, errors.py, ...)


def _imports(path: Path, module: str) -> set[str]:
    """The hybrid_dyn modules ``path`` imports (each resolved to a module file that exists)."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            names = [target] + [f"{target}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            if name.startswith("hybrid_dyn") and _exists(name):
                found.add(name)
    found.discard(module)
    return found


def _exists(module: str) -> bool:
    rel = Path(*module.split("."))
    return (SRC / rel).with_suffix(".py").is_file() or (SRC / rel / "__init__.py").is_file()


def _graph() -> dict[str, set[str]]:
    return {_module_name(p): _imports(p, _module_name(p)) for p in sorted(PACKAGE.rglob("*.py"))}


def test_no_module_imports_from_a_layer_above_its_own():
    upward = [f"{m} (layer {LAYERS[_layer(m)] or 'shared'}) imports {t} (layer {LAYERS[_layer(t)]})"
              for m, targets in _graph().items() if _layer(m) < len(LAYERS)
              for t in sorted(targets) if _layer(t) > _layer(m)]
    assert not upward, "\n".join(upward)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan); a package's ``__init__``
    importing its own submodules is not a circle, so edges from a package to its submodules are left out."""
    edges = {m: {t for t in ts if not t.startswith(m + ".")} for m, ts in graph.items()}
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_no_import_circles():
    assert _cycles(_graph()) == []


def test_the_checks_see_a_circle_and_an_upward_import():
    """The two checks above can fail: a made-up graph with a circle is found, and the layer rule ranks
    analytic above data."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _layer("hybrid_dyn.analytic.robot") > _layer("hybrid_dyn.data.dataset") > _layer("hybrid_dyn.registry")
    assert "hybrid_dyn.analytic.robot" in _imports(PACKAGE / "analytic" / "method_declaration.py",
                                                       "hybrid_dyn.analytic.method_declaration")


def test_no_two_modules_share_a_file_name():
    """A file name says what the module holds, once in the package (``__init__.py`` and ``cli.py`` aside)."""
    seen: dict[str, list[str]] = {}
    for p in PACKAGE.rglob("*.py"):
        if p.name not in ("__init__.py", "cli.py"):
            seen.setdefault(p.name, []).append(str(p.relative_to(PACKAGE)))
    assert {n: ps for n, ps in seen.items() if len(ps) > 1} == {}


def test_the_source_and_the_tests_cite_no_issue_numbers():
    """The code says what it is; how it came to be so is in CHANGELOG.md."""
    import re

    tests = Path(__file__).resolve().parents[1]
    cite = re.compile(r"\bissues? \d+", re.IGNORECASE)
    files = [*PACKAGE.rglob("*.py"), *tests.rglob("*.py")]
    found = [f"{p}:{i}" for p in files for i, line in enumerate(p.read_text().splitlines(), 1) if cite.search(line)]
    assert found == []
