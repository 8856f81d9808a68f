"""The package's import graph has no circles and no arrow from a lower layer up:
data flows model -> stipples -> optics -> toolpaths -> files, the simulator
reads the same toolpaths, and the jobs and the command line sit on top. Imports
made inside functions count."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
#: The layers, lowest first: a module may import its own layer's and lower ones'.
#: A package names every module under it; ``specholo`` is the package's front
#: page (it re-exports the setup's dataclasses).
LAYERS: list[set[str]] = [
    {"specholo.errors", "specholo._memory", "specholo._threads", "specholo._pages",
     "specholo._compiling"},
    {"specholo.readback"},
    {"specholo.setup", "specholo"},
    {"specholo.optics"},
    {"specholo.hosts"},
    {"specholo.scene"},
    {"specholo.visibility"},
    {"specholo.toolpaths"},
    {"specholo.fabrication"},
    {"specholo.simulation"},
    {"specholo.preview"},
    {"specholo.folder", "specholo.folders", "specholo.staging"},
    {"specholo.jobs.plate_settings"},
    {"specholo.jobs.plate_common"},
    {"specholo.jobs.flat.settings", "specholo.jobs.ridged.settings"},
    {"specholo.jobs.flat.design"},
    {"specholo.jobs.flat.folder"},
    {"specholo.jobs.flat.density", "specholo.jobs.ridged.design",
     "specholo.jobs.composition.design", "specholo.jobs.spin.design",
     "specholo.jobs.steady.design", "specholo.jobs.flat.coupon", "specholo._precompile"},
    {"specholo.jobs"},
    {"specholo.studio"},
    {"specholo_cli"},
]


def import_graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports (anywhere in its body)."""
    modules = {}
    for f in SRC.rglob("*.py"):
        name = ".".join(f.relative_to(SRC).with_suffix("").parts)
        modules[name.removesuffix(".__init__")] = f
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for name, f in modules.items():
        package = name if f.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            targets: list[str] = []
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")
                    base = ".".join(parts[:len(parts) - node.level + 1] + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                           for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            graph[name].update(t for t in targets if t in modules and t != name)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan's)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                on.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def layer_of(module: str) -> int:
    """Index in :data:`LAYERS` of the longest name that is the module or holds it."""
    best, found = -1, -1
    for i, layer in enumerate(LAYERS):
        for name in layer:
            if (module == name or module.startswith(name + ".")) and len(name) > best:
                best, found = len(name), i
    return found


def upward(graph: dict[str, set[str]]) -> list[str]:
    """Every import of a higher layer's module, as "importer -> imported"."""
    return [f"{a} -> {b}" for a in sorted(graph) for b in sorted(graph[a])
            if layer_of(b) > layer_of(a)]


def test_the_finder_sees_a_circle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_circles():
    graph = import_graph()
    flat = "specholo.jobs.flat.folder"
    assert flat in graph and graph[flat], "graph not read"
    assert cycles(graph) == []


def test_every_module_has_a_layer():
    assert [m for m in import_graph() if layer_of(m) < 0] == []


def test_the_layer_rule_sees_an_upward_arrow():
    assert upward({"specholo.toolpaths.striped": {"specholo.jobs.flat.folder"}}) == [
        "specholo.toolpaths.striped -> specholo.jobs.flat.folder"]
    assert upward({"specholo.jobs.flat.folder": {"specholo.toolpaths.striped"}}) == []


def test_no_arrow_from_a_lower_layer_up():
    assert upward(import_graph()) == []


#: Rooms of one layer that must not import each other: a program and a drawing
#: are both made from the grooves, by what every exporter shares
#: (``fabrication.exporting``), never one from the other.
APART = [("specholo.fabrication.programs", "specholo.fabrication.drawings")]


def test_programs_and_drawings_stand_apart():
    graph = import_graph()
    crossing = [f"{a} -> {b}" for a in sorted(graph) for b in sorted(graph[a])
                for one, other in APART for x, y in ((one, other), (other, one))
                if a.startswith(x + ".") and b.startswith(y + ".")]
    assert any(m.startswith("specholo.fabrication.programs.") for m in graph)
    assert crossing == []


#: The kinds of hologram, one package each under ``specholo.jobs`` (a flat
#: plate's test coupon, cut for its long job with its striping and settings, is
#: in the flat plate's package; a ridged plate shares with the flat one only
#: what lies below the kinds: ``jobs.plate_settings`` and ``jobs.plate_common``).
KINDS = ("flat", "ridged", "composition", "spin", "steady")


def _kind(module: str) -> str | None:
    parts = module.split(".")
    if len(parts) > 2 and parts[:2] == ["specholo", "jobs"] and parts[2] in KINDS:
        return parts[2]
    return None


def test_a_kind_imports_no_other_kind():
    graph = import_graph()
    assert {_kind(m) for m in graph} >= set(KINDS)
    crossing = sorted(f"{a} -> {b}" for a in graph for b in graph[a]
                      if _kind(a) and _kind(b) and _kind(a) != _kind(b))
    assert crossing == []
