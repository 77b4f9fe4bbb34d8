"""The package's layering (docs/architecture.md): no import cycle between straylight's modules
or sub-packages, and each sub-package imports only the layers below its own.

The graph is read from the source with ``ast``: every ``import`` and ``from ... import`` of a
``straylight`` module counts, at module level or inside a function (a lazy import is still a
dependency).  Imports under ``if TYPE_CHECKING:`` never run, so they make no cycle; they still
name a type of the layer they import from, so the layering counts them (a function of ``sky``
annotated with the config's ``Campaign`` depends on the config layer, whether or not the import
runs).  The table below is the one docs/architecture.md shows; a new sub-package or top-level
module must be placed in it.
"""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "straylight"

#: the layers, lowest first: a sub-package (or top-level module) may import the packages of
#: earlier layers only.  "straylight" is the package's own ``__init__`` (the public facade).
LAYERS = (
    ("_scm_version",),
    ("errors", "_version"),
    ("util",),
    ("execution",),
    ("sky",),
    ("config",),
    ("optics",),
    ("catalog",),
    ("sources",),
    ("model",),
    ("storage",),
    ("limits",),
    ("cube", "image"),
    ("planning",),
    ("paper",),
    ("skymodel",),
    ("api",),
    ("plots", "configdoc", "runner"),
    ("straylight",),
    ("cli",),
)
RANK = {name: i for i, layer in enumerate(LAYERS) for name in layer}


def _unit(module: str) -> str:
    """The sub-package (or top-level module) a dotted module name belongs to."""
    parts = module.split(".")
    name = parts[1] if len(parts) > 1 else "straylight"
    return name


def _modules(package: Path = PACKAGE) -> dict:
    """Every module of ``package`` (a folder named ``straylight``): dotted name -> path."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _type_checking_nodes(tree) -> set:
    """Import nodes inside ``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``) blocks."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            t = node.test
            if (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
                isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
            ):
                skip.update(id(n) for b in node.body for n in ast.walk(b))
    return skip


def _imports(name: str, path: Path, modules, type_only: bool = False) -> list[tuple[str, int]]:
    """(imported straylight module, line) for every import in the module ``name``; ``modules``:
    every module's name (``from a import b`` imports the module ``a.b`` when there is one).
    ``type_only``: also the imports under ``if TYPE_CHECKING:``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    skip = set() if type_only else _type_checking_nodes(tree)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            found += [
                (f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base, node.lineno)
                for a in node.names
            ]
    return [(m, line) for m, line in found if m == "straylight" or m.startswith("straylight.")]


def _module_edges(package: Path = PACKAGE, type_only: bool = False) -> dict:
    """{(importing module, imported module): [where, ...]} between different modules of
    ``package`` (an import of ``a.b.c`` is an edge to ``a.b.c``: the packages above it run
    first, but a cycle through them shows as a cycle of the modules that import them)."""
    edges: dict = {}
    modules = _modules(package)
    for name, path in modules.items():
        for target, line in _imports(name, path, modules, type_only):
            if target != name and target in modules:
                edges.setdefault((name, target), []).append(
                    f"{path.relative_to(package.parent)}:{line} imports {target}"
                )
    return edges


def _package_edges(package: Path = PACKAGE, type_only: bool = False) -> dict:
    """{(importing unit, imported unit): [where, ...]} between different units."""
    edges: dict = {}
    modules = _modules(package)
    for name, path in modules.items():
        for target, line in _imports(name, path, modules, type_only):
            a, b = _unit(name), _unit(target)
            if a != b:
                edges.setdefault((a, b), []).append(
                    f"{path.relative_to(package.parent)}:{line} imports {target}"
                )
    return edges


def _cycle(edges) -> list | None:
    """One cycle of the directed graph ``edges`` as a list of nodes, or None."""
    cycles = _cycles(edges)
    return cycles[0] if cycles else None


def _cycles(edges) -> list[list]:
    """One cycle (a list of nodes, the first repeated at the end) in each strongly connected
    component of the directed graph ``edges`` that has one (Tarjan's algorithm), in sorted
    order: every knot of mutually importing modules is named, not only the first found."""
    graph: dict = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
        graph.setdefault(b, set())
    index: dict = {}
    low: dict = {}
    stack: list = []
    on_stack: set = set()
    components: list = []

    def connect(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(component)

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return sorted(_cycle_within(graph, c) for c in components)


def _cycle_within(graph: dict, component: set) -> list:
    """A cycle through the smallest node of a strongly connected ``component``: the shortest
    path back to it (breadth first), as nodes with the first repeated at the end."""
    start = min(component)
    parent = {start: None}
    queue = [start]
    for v in queue:
        for w in sorted(graph[v] & component):
            if w == start:
                path = [v]
                while parent[path[-1]] is not None:
                    path.append(parent[path[-1]])
                return path[::-1] + [start]
            if w not in parent:
                parent[w] = v
                queue.append(w)
    raise AssertionError("not a strongly connected component")


def _describe(cycles, edges) -> str:
    return "\n".join(
        " -> ".join(c) + ":\n" + "\n".join("    " + w for a, b in zip(c, c[1:]) for w in edges[(a, b)])
        for c in cycles
    )


def _layer_violations(edges) -> list[str]:
    return [
        w
        for (a, b), where in sorted(edges.items())
        if a in RANK and b in RANK and RANK[b] >= RANK[a]
        for w in where
    ]


def test_every_package_is_placed_in_a_layer():
    units = {_unit(name) for name in _modules()}
    assert units - set(RANK) == set(), "place these in LAYERS (and docs/architecture.md)"


def test_no_import_cycle_between_packages():
    edges = _package_edges()
    cycles = _cycles(edges)
    assert cycles == [], "import cycles between packages:\n" + _describe(cycles, edges)


def test_no_import_cycle_between_modules():
    edges = _module_edges()
    cycles = _cycles(edges)
    assert cycles == [], "import cycles between modules:\n" + _describe(cycles, edges)


def test_each_package_imports_only_lower_layers():
    """Type-only imports count: a lower layer does not name a higher layer's types either."""
    bad = _layer_violations(_package_edges(type_only=True))
    assert bad == [], "imports against the layering (tests/test_architecture.py LAYERS):\n" + "\n".join(bad)


def _write(root: Path, files: dict) -> Path:
    for rel, text in files.items():
        path = root / "straylight" / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root / "straylight"


def test_the_checks_see_a_lazy_import_and_a_cycle():
    """The graph counts an import inside a function and the cycle search finds a 2-cycle."""
    edges = _package_edges()
    assert ("cube", "model") in edges  # cube.store builds the model inside a function
    assert _cycle({("a", "b"): [], ("b", "a"): []}) in (["a", "b", "a"], ["b", "a", "b"])
    assert _cycle({("a", "b"): [], ("b", "c"): []}) is None


def test_the_module_checks_on_a_small_package(tmp_path):
    """The module graph counts an import inside a function and leaves out one under
    ``if TYPE_CHECKING:``; the cycle search names every knot; the layering sees a type-only
    import of a higher layer (a sky module annotated with the config's Campaign)."""
    package = _write(
        tmp_path,
        {
            "__init__.py": "",
            "config.py": "from straylight.sky import observing\n",
            "sky/__init__.py": "",
            "sky/observing.py": (
                "from typing import TYPE_CHECKING\nfrom straylight.sky.orbit import f\n"
                "if TYPE_CHECKING:\n    from straylight.config import Campaign\n"
            ),
            "sky/orbit.py": "def f():\n    from straylight.sky import observing\n",
            "sky/time.py": "from . import frames\n",
            "sky/frames.py": "import straylight.sky.time\n",
        },
    )
    edges = _module_edges(package)
    assert ("straylight.sky.orbit", "straylight.sky.observing") in edges  # lazy
    assert ("straylight.sky.observing", "straylight.config") not in edges  # type only
    assert _cycles(edges) == [
        ["straylight.sky.frames", "straylight.sky.time", "straylight.sky.frames"],
        ["straylight.sky.observing", "straylight.sky.orbit", "straylight.sky.observing"],
    ]
    assert _cycles(_package_edges(package)) == []
    assert _layer_violations(_package_edges(package)) == []
    assert _layer_violations(_package_edges(package, type_only=True)) == [
        "straylight/sky/observing.py:4 imports straylight.config"
    ]
    assert _cycle({("a", "b"): [], ("b", "a"): []}) == ["a", "b", "a"]
    assert _cycle({("a", "b"): [], ("b", "c"): []}) is None
    assert _cycles({("a", "b"): [], ("b", "c"): [], ("c", "a"): [], ("c", "d"): [], ("d", "c"): []}) == [
        ["a", "b", "c", "a"]
    ]


def test_the_table_is_the_one_in_the_docs():
    """docs/architecture.md lists the same layers in the same order."""
    doc = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    rows = [line for line in doc.splitlines() if line.startswith("| ") and "`" in line.split("|")[1]]
    listed = [tuple(n.strip().strip("`") for n in row.split("|")[1].split(",")) for row in rows]
    assert listed == [tuple(n for n in layer) for layer in LAYERS]


#: the longest a module of the library may be (issue: a module a newcomer can read at once)
MAX_MODULE_LINES = 600


def test_no_module_is_longer_than_the_limit():
    """Every straylight/**/*.py has at most MAX_MODULE_LINES lines."""
    long = {
        str(p.relative_to(PACKAGE.parent)): n
        for p in sorted(PACKAGE.rglob("*.py"))
        if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES
    }
    assert long == {}


#: what the sources' base (straylight.sources.context: Samples, Source, SourceContext) may
#: import from straylight.sources, directly or through them: shared modules, no source of light
SOURCES_BASE_MAY_REACH = {
    "straylight.sources",
    "straylight.sources.context",
    "straylight.sources.offfield",
    "straylight.sources.photometry",
    "straylight.sources.rates",
}


def test_the_sources_base_imports_no_source():
    """Every source builds on straylight.sources.context; it reaches (transitively) only the
    shared modules of SOURCES_BASE_MAY_REACH, never a source (the zodiacal floor is passed in)."""
    edges = _module_edges()
    reached, todo = set(), ["straylight.sources.context"]
    while todo:
        a = todo.pop()
        for x, b in edges:
            if x == a and b.startswith("straylight.sources") and b not in reached:
                reached.add(b)
                todo.append(b)
    assert reached - SOURCES_BASE_MAY_REACH == set()


def test_no_source_is_built_from_another():
    """The registry's factories build a source from the model's context, policy and shared
    parts (``model.shared``), never by asking the model for another source (``model.source``)."""
    path = PACKAGE / "model" / "registry.py"
    calls = [
        f"model/registry.py:{node.lineno}"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "source"
    ]
    assert calls == []
