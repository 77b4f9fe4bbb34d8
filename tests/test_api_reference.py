"""The API reference (docs/api/) builds from the docstrings with Sphinx and numpydoc, warnings
as errors, and documents every name ``straylight.__all__`` states.

Sphinx and numpydoc are in the ``test`` extra, so ``make test`` (and CI) runs the build; where
they are not installed the build test skips and says so.
"""

import re
import subprocess
import sys
from pathlib import Path

import pytest

import straylight

DOCS = Path(__file__).resolve().parents[1] / "docs" / "api"

#: an autodoc directive and the name it documents, e.g. ``.. autofunction:: sky_background``
_DIRECTIVE = re.compile(r"^\.\. (?:auto\w+|data)::\s+(\S+)", re.M)


def documented_names(docs: Path = DOCS) -> set[str]:
    """The ``straylight`` names the reference's pages document: the directives' targets under
    ``.. currentmodule:: straylight`` or spelt ``straylight.<name>``."""
    names = set()
    for page in sorted(docs.glob("*.rst")):
        module = None
        for line in page.read_text().splitlines():
            if line.startswith(".. currentmodule::"):
                module = line.split("::", 1)[1].strip()
            m = _DIRECTIVE.match(line)
            if not m:
                continue
            target = m.group(1)
            if target.startswith("straylight.") and target.count(".") == 1:
                names.add(target.split(".", 1)[1])
            elif "." not in target and module == "straylight":
                names.add(target)
    return names


def test_reference_documents_every_public_name():
    missing = sorted(set(straylight.__all__) - documented_names())
    assert not missing, f"docs/api/ documents no page for straylight.{missing}"


def test_public_names_resolve():
    # every name __all__ states is importable from straylight (the lazy ones included)
    for name in straylight.__all__:
        assert getattr(straylight, name) is not None, name


def test_reference_builds_without_warnings(tmp_path):
    for module in ("sphinx", "numpydoc"):
        pytest.importorskip(
            module, reason=f"{module} is not installed: pip install -e '.[test]' (or '.[docs]')"
        )
    build = ["-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(DOCS), str(tmp_path / "html")]
    out = subprocess.run(
        [sys.executable, *build],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, f"sphinx-build failed:\n{out.stderr[-5000:]}"
    page = (tmp_path / "html" / "sky.html").read_text()
    # the numpydoc sections are rendered: sky_background's Parameters list names its arguments
    assert "Parameters" in page and "coord" in page and "SkyModel" in page
