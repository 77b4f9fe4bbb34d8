"""Where the compiled (numba) kernels are cached: beside the tables, shared by every install.

Numba caches a ``cache=True`` kernel next to its module (``__pycache__``), keyed by the file's
folder, so a fresh install (a new venv, a wheel in a read-only site-packages) compiles every
kernel on its first call, seconds before the first answer.  The kernels of this package are
cached instead in the table cache (:func:`straylight.util.io.cache_dir`, ``numba/``) under their
path inside the package, keyed by their source's content (a SHA-256 of the file), numba's
version and the processor: an install whose modules are the same reads the kernels an earlier
one compiled, and the first table build compiles them ahead.  ``NUMBA_CACHE_DIR``, when set,
wins (numba's own locators then).

The package's modules take ``njit`` from here (``from straylight.util.kernel_cache import
njit``), so the locator is in place before the first kernel is declared.
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

from numba import njit
from numba.core import caching

from straylight.util.io import cache_dir

__all__ = ["njit", "kernel_cache_dir"]

_PACKAGE = Path(__file__).resolve().parents[1]


@functools.lru_cache(maxsize=None)
def _source_digest(path: str) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def kernel_cache_dir() -> Path:
    """The folder of the package's compiled kernels: ``<table cache>/numba``."""
    return cache_dir() / "numba"


class _PackageLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
    """Numba cache locator for this package's modules: ``<table cache>/numba/<module's folder in
    the package>``, the same for every install."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        rel = Path(py_file).resolve().relative_to(_PACKAGE).parent
        self._cache_path = str(kernel_cache_dir() / "straylight" / rel)

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        """The source's content (not its time: a new install's files are new)."""
        return _source_digest(self._py_file)

    @classmethod
    def from_function(cls, py_func, py_file):
        if os.environ.get("NUMBA_CACHE_DIR"):  # the user's choice: numba's own locator
            return None
        try:
            Path(py_file).resolve().relative_to(_PACKAGE)
        except ValueError:  # not one of ours
            return None
        return super().from_function(py_func, py_file)


_IMPL = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # renamed in numba 0.62
if _PackageLocator not in _IMPL._locator_classes:
    _IMPL._locator_classes.insert(0, _PackageLocator)
