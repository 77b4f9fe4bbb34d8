"""Function size limits (issue #54 item 5): outside the compiled kernels, no function in
straylight/ (methods and nested functions included) is over 80 lines or takes more than 8
parameters.

Lines: from the ``def`` (decorators excluded) to the function's last line, docstring included.
Parameters: positional-only, positional and keyword-only, ``self``/``cls`` of a method not
counted; ``*args`` and ``**kwargs`` count one each.  A compiled kernel is a function decorated
with numba's ``njit``/``jit``/``vectorize``/``guvectorize``/``stencil``/``cfunc`` (directly or
through :mod:`straylight.util.kernel_cache`).
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "straylight"
MAX_LINES = 80
MAX_PARAMETERS = 8
_KERNEL_DECORATORS = {"njit", "jit", "vectorize", "guvectorize", "stencil", "cfunc"}

# Functions allowed over the limits while they are being rewritten, with their size then
# (lines, parameters): an entry may only shrink, and goes once its function meets the limits.
EXEMPT: dict[str, tuple[int, int]] = {}


def _decorator_name(node: ast.expr) -> str:
    if isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Attribute):
        return node.attr
    return node.id if isinstance(node, ast.Name) else ""


def _is_kernel(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    return any(_decorator_name(d) in _KERNEL_DECORATORS for d in fn.decorator_list)


def _parameters(fn: ast.FunctionDef | ast.AsyncFunctionDef, in_class: bool) -> int:
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    if in_class and names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names) + (a.vararg is not None) + (a.kwarg is not None)


def _functions(node: ast.AST, prefix: str = "", in_class: bool = False):
    """(qualified name, lines, parameters, is kernel) of every function under ``node``."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
            name = prefix + child.name
            yield name, child.end_lineno - child.lineno + 1, _parameters(child, in_class), _is_kernel(child)
            yield from _functions(child, name + ".")
        elif isinstance(child, ast.ClassDef):
            yield from _functions(child, prefix + child.name + ".", in_class=True)
        else:
            yield from _functions(child, prefix, in_class)


def _sizes(package: Path = PACKAGE) -> dict[str, tuple[int, int, bool]]:
    out = {}
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package).as_posix()
        for name, lines, params, kernel in _functions(ast.parse(path.read_text(), str(path))):
            out[f"{rel}::{name}"] = (lines, params, kernel)
    return out


def _over(lines: int, params: int) -> bool:
    return lines > MAX_LINES or params > MAX_PARAMETERS


def test_functions_within_limits():
    over = [
        f"{key}: {lines} lines, {params} parameters"
        for key, (lines, params, kernel) in _sizes().items()
        if not kernel and key not in EXEMPT and _over(lines, params)
    ]
    assert not over, f"over {MAX_LINES} lines or {MAX_PARAMETERS} parameters:\n" + "\n".join(over)


def test_exemptions_only_shrink():
    sizes = _sizes()
    stale = [key for key in EXEMPT if key not in sizes or not _over(*sizes[key][:2])]
    grown = [
        f"{key}: {sizes[key][:2]} > {EXEMPT[key]}"
        for key in EXEMPT
        if key in sizes
        and (
            sizes[key][0] > max(EXEMPT[key][0], MAX_LINES)
            or sizes[key][1] > max(EXEMPT[key][1], MAX_PARAMETERS)
        )
    ]
    assert not stale, "within the limits or gone now: remove from EXEMPT:\n" + "\n".join(stale)
    assert not grown, "an exempt function grew:\n" + "\n".join(grown)


def test_the_walk_sees_methods_nested_functions_and_kernels(tmp_path):
    """The walk on a known module: a 81-line method, a nested function with 9 parameters
    (self not counted, *args and **kwargs one each) and a compiled kernel over both limits."""
    method_body = "\n".join(f"        x{i} = {i}" for i in range(78))
    kernel_body = "\n".join(f"    x{i} = {i}" for i in range(78))
    source = [
        "from numba import njit",
        "class A:",
        "    def long(self):",
        '        """81 lines."""',
        method_body,
        "        return x0",
        "def outer():",
        "    def inner(a, b, c, d, e, f, g, *args, **kwargs):",
        "        return a",
        "    return inner",
        "@njit(cache=True)",
        "def kernel(a, b, c, d, e, f, g, h, i):",
        kernel_body,
        "    return a",
    ]
    (tmp_path / "m.py").write_text("\n".join(source) + "\n")
    sizes = _sizes(tmp_path)
    assert sizes["m.py::A.long"] == (81, 0, False)
    assert sizes["m.py::outer.inner"] == (2, 9, False)
    assert sizes["m.py::kernel"][1:] == (9, True)
    assert [k for k, (n, p, kern) in sizes.items() if not kern and _over(n, p)] == [
        "m.py::A.long",
        "m.py::outer.inner",
    ]
