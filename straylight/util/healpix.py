"""healpy for the pixel functions, without its plotting functions in a pipeline process.

healpy imports its plotting functions (``healpy.visufunc``: matplotlib's axes and fonts) only
when ``import matplotlib`` succeeds.  A pipeline job or worker that computes (the footprint, the
cube's workers, the limits' FITS maps, the workflow's own parse) needs none of them, and
importing them is nearly half of ``import healpy``'s time (docs/performance.md).
Such a process opts in with :func:`load_without_plotting` at its start; everywhere else (the
Python API, a notebook) :func:`healpy` is ``import healpy``.  The figures import
``healpy.visufunc`` or ``healpy.projaxes`` by name, which works either way.
"""

from __future__ import annotations

import sys
import threading

__all__ = ["load_without_plotting", "healpy"]

_PLOTLESS = False  # set by load_without_plotting
_LOCK = threading.Lock()


def load_without_plotting() -> None:
    """Have :func:`healpy` load healpy without its plotting functions in this process: a
    pipeline job or worker, called at its start (before anything imports healpy).  A process
    that has loaded healpy or matplotlib already keeps them as they are."""
    global _PLOTLESS
    _PLOTLESS = True


def healpy():
    """The healpy module.  In a process that asked for it (:func:`load_without_plotting`) and
    has not loaded healpy or matplotlib yet, healpy is imported with matplotlib hidden from it:
    the same pixel functions, without ``healpy.mollview`` and the other plotting names in its
    namespace.  Thread-safe (a Dask worker's threads may ask at once)."""
    with _LOCK:
        if not _PLOTLESS or "healpy" in sys.modules or "matplotlib" in sys.modules:
            import healpy as hp

            return hp
        # astropy's modules that note at import whether matplotlib is installed, loaded first
        # with matplotlib visible (astropy.time's plot_date format); healpy loads them anyway
        import astropy.coordinates  # noqa: F401
        import astropy.io.fits  # noqa: F401
        import astropy.time  # noqa: F401

        sys.modules["matplotlib"] = None  # `import matplotlib` raises ImportError while healpy loads
        try:
            import healpy as hp
        finally:
            del sys.modules["matplotlib"]
        return hp
