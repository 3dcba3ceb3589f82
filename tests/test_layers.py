"""The package's import layers (``[tool.importlinter]`` in pyproject.toml, docs/guide/architecture.md):
the contract holds with no exception, every module sits in a layer, and there is no import cycle
among the package's modules at all. The import graph is grimp's (import-linter's), which sees
imports inside functions too."""
from __future__ import annotations

from pathlib import Path

import grimp
import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python < 3.11
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "hydrogen"


def _contract() -> dict:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    (contract,) = [c for c in config["contracts"] if c["type"] == "layers"]
    return contract


def _layers() -> list:
    """Each layer's modules, top first (``a | b`` independent, ``a : b`` not)."""
    return [[m.strip() for m in layer.replace(":", "|").split("|")] for layer in _contract()["layers"]]


@pytest.fixture(scope="module")
def graph():
    return grimp.build_graph(PACKAGE, cache_dir=None)


def _imports(graph) -> dict:
    return {m: set(graph.find_modules_directly_imported_by(m)) for m in graph.modules}


def layer_of(module: str, layers: list):
    """Index of the layer holding ``module`` (its own entry or an ancestor's, the longest), or None."""
    best = None
    for i, layer in enumerate(layers):
        for entry in layer:
            if (module == entry or module.startswith(entry + ".")) and (best is None or len(entry) > len(best[1])):
                best = (i, entry)
    return None if best is None else best[0]


def cycles(imports: dict) -> list:
    """The import cycles of ``imports`` (module -> modules it imports): its strongly connected
    components of more than one module, each sorted (Tarjan's algorithm, iterative)."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []
    for start in sorted(imports):
        if start in index:
            continue
        work = [(start, iter(sorted(imports.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, edges = work[-1]
            nxt = next(edges, None)
            if nxt is not None:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(imports.get(nxt, ())))))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    m = stack.pop()
                    on_stack.discard(m)
                    comp.append(m)
                    if m == node:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_the_layers_contract_holds_with_no_exception():
    from importlinter.cli import lint_imports

    assert not _contract().get("ignore_imports"), "the layers contract lists imports it ignores"
    assert lint_imports(config_filename=str(ROOT / "pyproject.toml")) == 0


def test_every_module_sits_in_a_layer(graph):
    """A module outside every layer would escape the contract: the package's root (its public
    facade) and a subpackage's empty ``__init__`` alone may."""
    layers = _layers()
    imports = _imports(graph)
    loose = [m for m in sorted(graph.modules) if m != PACKAGE and layer_of(m, layers) is None
             and not (graph.find_children(m) and not imports[m])]
    assert not loose, f"modules in no layer of pyproject.toml's [tool.importlinter]: {loose}"


def test_no_import_cycle(graph):
    """Every strongly connected component of the import graph is one module: no two modules
    import each other, however indirectly, not even inside one layer or from inside a function."""
    found = cycles(_imports(graph))
    assert not found, f"import cycles among the package's modules: {found}"


def test_the_cycle_check_finds_every_cycle():
    imports = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a", "p.d"}, "p.d": set(), "p.e": {"p.e", "p.d"},
               "p.f": {"p.g"}, "p.g": {"p.f"}}
    assert cycles(imports) == [["p.a", "p.b", "p.c"], ["p.f", "p.g"]]
    assert cycles({"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": set()}) == []


def test_a_module_belongs_to_its_closest_layer_entry():
    layers = [["hydrogen.codegen.generate"], ["hydrogen.symbolic.functions", "hydrogen.symbolic.plant"],
              ["hydrogen.codegen.sympy_to_casadi"], ["hydrogen.simulation"]]
    assert layer_of("hydrogen.codegen.sympy_to_casadi", layers) == 2
    assert layer_of("hydrogen.symbolic.plant", layers) == 1
    assert layer_of("hydrogen.simulation.sweep", layers) == 3
    assert layer_of("hydrogen.symbolic.tree", layers) is None
