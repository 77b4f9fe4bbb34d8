"""The package's layering (docs/architecture.md): no import cycle between straylight's
sub-packages, and each sub-package imports only the layers below its own.

The graph is read from the source with ``ast``: every ``import`` and ``from ... import`` of a
``straylight`` module counts, at module level or inside a function (a lazy import is still a
dependency); imports under ``if TYPE_CHECKING:`` are annotations only and do not count.  The
table below is the one docs/architecture.md shows; a new sub-package or top-level module must be
placed in it.
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
    ("sky",),
    ("config",),
    ("optics",),
    ("catalog",),
    ("sources",),
    ("model",),
    ("survey", "image"),
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


def _modules() -> dict:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _type_checking_nodes(tree) -> set:
    """Import nodes inside ``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``) blocks."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            t = node.test
            if (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or \
                    (isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"):
                skip.update(id(n) for b in node.body for n in ast.walk(b))
    return skip


def _imports(name: str, path: Path, modules) -> list[tuple[str, int]]:
    """(imported straylight module, line) for every import in the module ``name``; ``modules``:
    every module's name (``from a import b`` imports the module ``a.b`` when there is one)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    skip = _type_checking_nodes(tree)
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
                anchor = anchor[:len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            found += [(f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base, node.lineno)
                      for a in node.names]
    return [(m, line) for m, line in found if m == "straylight" or m.startswith("straylight.")]


def _package_edges() -> dict:
    """{(importing unit, imported unit): [where, ...]} between different units."""
    edges: dict = {}
    modules = _modules()
    for name, path in modules.items():
        for target, line in _imports(name, path, modules):
            a, b = _unit(name), _unit(target)
            if a != b:
                edges.setdefault((a, b), []).append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {target}")
    return edges


def _cycle(edges) -> list | None:
    """One cycle of the directed graph ``edges`` as a list of nodes, or None."""
    graph: dict = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
    state: dict = {}
    stack: list = []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state:
                found = visit(m)
                if found:
                    return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state:
            found = visit(n)
            if found:
                return found
    return None


def test_every_package_is_placed_in_a_layer():
    units = {_unit(name) for name in _modules()}
    assert units - set(RANK) == set(), "place these in LAYERS (and docs/architecture.md)"


def test_no_import_cycle_between_packages():
    edges = _package_edges()
    cycle = _cycle(edges)
    assert cycle is None, "import cycle " + " -> ".join(cycle) + ":\n" + "\n".join(
        w for a, b in zip(cycle, cycle[1:]) for w in edges[(a, b)])


def test_each_package_imports_only_lower_layers():
    bad = [w for (a, b), where in sorted(_package_edges().items())
           if a in RANK and b in RANK and RANK[b] >= RANK[a] for w in where]
    assert bad == [], "imports against the layering (tests/test_architecture.py LAYERS):\n" + "\n".join(bad)


def test_the_checks_see_a_lazy_import_and_a_cycle():
    """The graph counts an import inside a function and the cycle search finds a 2-cycle."""
    edges = _package_edges()
    assert ("survey", "model") in edges  # survey.cube builds the model inside a function
    assert _cycle({("a", "b"): [], ("b", "a"): []}) in (["a", "b", "a"], ["b", "a", "b"])
    assert _cycle({("a", "b"): [], ("b", "c"): []}) is None


def test_the_table_is_the_one_in_the_docs():
    """docs/architecture.md lists the same layers in the same order."""
    doc = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    rows = [line for line in doc.splitlines() if line.startswith("| ") and "`" in line.split("|")[1]]
    listed = [tuple(n.strip().strip("`") for n in row.split("|")[1].split(",")) for row in rows]
    assert listed == [tuple(n for n in layer) for layer in LAYERS]
