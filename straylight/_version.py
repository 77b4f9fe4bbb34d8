"""The package version, importable from every layer.

setuptools-scm derives it from git when the package is built or installed (pip install, also
editable: the last tag and the commits since, e.g. ``0.1.dev690+g93d51f5``, with a date when
the tree had uncommitted changes) and writes it to ``straylight/_scm_version.py``, which git does
not track.  A source tree that was never installed has no such file: the installed
distribution's metadata is asked, else the version is ``0+unknown``.  A run from a checkout
records its exact commit separately (straylight.cube.provenance).
"""

try:
    from straylight._scm_version import __version__
except ImportError:  # never built or installed from this tree
    from importlib import metadata as _metadata

    try:
        __version__ = _metadata.version("straylight")
    except _metadata.PackageNotFoundError:
        __version__ = "0+unknown"

#: the commit the package was built from (setuptools-scm's short id, e.g. ``g93d51f5``; None:
#: unknown or built without git metadata)
try:
    from straylight._scm_version import __commit_id__ as build_commit
except ImportError:
    build_commit = None
