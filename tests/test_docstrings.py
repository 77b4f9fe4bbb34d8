"""Every public function and method of the covered parts of the package has a numpydoc
``Parameters`` section that names each of its parameters, and names none it does not take.

Public: a module whose dotted path has no part starting with ``_``; a top-level function, or a
method of a top-level class, whose name does not start with ``_`` (dunder methods are
documented in their class's docstring).  The parameters are the signature's, ``self`` and
``cls`` aside, ``*args`` and ``**kwargs`` by their names.  Read with ``ast``: nothing is
imported.

:data:`COVERED` lists the sub-packages and modules held to it.  Not listed yet: straylight/survey/,
straylight/sources/ and util/daskutil.py, being reorganised (issue #54); add each part here once
its functions are documented.
"""

import ast
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "straylight"

#: sub-packages (folders) and modules whose public functions are all documented
COVERED = (
    "__init__.py",
    "api.py",
    "configdoc.py",
    "errors.py",
    "runner.py",
    "skymodel.py",
    "catalog",
    "cli",
    "config",
    "image",
    "model",
    "optics",
    "paper",
    "plots",
    "sky",
    "util/gridinterp.py",
    "util/healpix.py",
    "util/io.py",
    "util/kernel_cache.py",
)

#: functions of covered parts left without the section for now: the survey's split (issue #54)
#: rewrites their docstrings' last lines, so the section is added once it has merged
PENDING = {
    "straylight/cli/sky.py sky_record",
    "straylight/plots/series.py pointing_series",
    "straylight/runner.py warn_if_large",
}

#: the numpydoc section headers (a line of one of these, then a line of dashes)
_SECTION = re.compile(r"^(\S[^\n]*)\n-{3,}$", re.M)


def _parameters(fn: ast.FunctionDef) -> list[str]:
    """The names of ``fn``'s parameters, ``self`` and ``cls`` aside."""
    a = fn.args
    names = [x.arg for x in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
    return [n for n in names if n not in ("self", "cls")]


def documented_names(docstring: str) -> list[str] | None:
    """The parameter names a cleaned docstring's ``Parameters`` section gives (``x : int``,
    ``x, y : float``, ``*args``, or a name alone), None without the section.

    Parameters
    ----------
    docstring : str
        A docstring as :func:`ast.get_docstring` returns it (indentation removed).
    """
    headers = list(_SECTION.finditer(docstring))
    for i, m in enumerate(headers):
        if m.group(1).strip() != "Parameters":
            continue
        end = headers[i + 1].start() if i + 1 < len(headers) else len(docstring)
        body = docstring[m.end() : end]
        names = []
        for line in body.splitlines():
            if line and not line[0].isspace():
                names += [n.strip().lstrip("*") for n in line.split(" : ")[0].split(",")]
        return [n for n in names if n]
    return None


def public_functions(path: Path):
    """``(qualified name, function node)`` of each public function and public method of a
    public class defined at the top level of the module at ``path``.

    Parameters
    ----------
    path : pathlib.Path
        A module's file.
    """
    tree = ast.parse(path.read_text())
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield node.name, node
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            for sub in node.body:
                if isinstance(sub, ast.FunctionDef | ast.AsyncFunctionDef):
                    yield f"{node.name}.{sub.name}", sub


def _overload(fn) -> bool:
    return any(getattr(d, "id", getattr(d, "attr", None)) == "overload" for d in fn.decorator_list)


def problems(part: str) -> list[str]:
    """What a part of the package lacks: each public function with parameters and no
    Parameters section, or whose section misses or adds a name.

    Parameters
    ----------
    part : str
        A sub-package's folder or a top-level module's file name under ``straylight/``.
    """
    root = PACKAGE / part
    paths = [root] if root.suffix == ".py" else sorted(root.rglob("*.py"))
    out = []
    for path in paths:
        rel = path.relative_to(PACKAGE.parent)
        if any(p.startswith("_") and p != "__init__.py" for p in rel.parts):
            continue
        for name, fn in public_functions(path):
            if fn.name.startswith("_") or _overload(fn) or f"{rel} {name}" in PENDING:
                continue
            params = _parameters(fn)
            if not params:
                continue
            documented = documented_names(ast.get_docstring(fn) or "")
            if documented is None:
                out.append(f"{rel}:{fn.lineno} {name}: no Parameters section")
                continue
            missing = [p for p in params if p not in documented]
            extra = [p for p in documented if p not in params]
            if missing or extra:
                out.append(f"{rel}:{fn.lineno} {name}: Parameters lacks {missing}, names {extra} not taken")
    return out


@pytest.mark.parametrize("part", COVERED)
def test_public_functions_document_their_parameters(part):
    assert (PACKAGE / part).exists(), f"straylight/{part} is gone: update COVERED"
    found = problems(part)
    assert not found, f"{len(found)} public functions in straylight/{part}:\n" + "\n".join(found)


def test_documented_names_reads_numpydoc():
    doc = "Sum.\n\nParameters\n----------\nx, y : float\n    Values, m.\n*args\n    More.\n\n"
    doc += "Returns\n-------\nfloat\n    m."
    assert documented_names(doc) == ["x", "y", "args"]
    assert documented_names("Sum of ``x`` and ``y``.") is None
