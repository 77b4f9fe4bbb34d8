"""healpy for the pixel functions, without its plotting functions where nothing has drawn yet.

healpy imports its plotting functions (``healpy.visufunc``: matplotlib's axes and fonts) only
when ``import matplotlib`` succeeds.  A process that computes (the footprint, the cube's workers,
the limits' FITS maps, the workflow's own parse) needs none of them, and importing them costs
~0.35 s of the ~0.8 s that ``import healpy`` takes on the development machine.  The figures
import ``healpy.visufunc`` or ``healpy.projaxes`` by name, which works either way.
"""
from __future__ import annotations

import sys


def healpy():
    """The healpy module: imported here, if no process code has imported it yet, with
    matplotlib hidden from it unless matplotlib is already loaded (then healpy comes whole, as
    ``import healpy`` gives it).  Its pixel functions are the same either way; only
    ``healpy.mollview`` and the other plotting names may be missing from its namespace."""
    if "healpy" in sys.modules:
        return sys.modules["healpy"]
    if "matplotlib" in sys.modules:
        import healpy as hp

        return hp
    sys.modules["matplotlib"] = None  # `import matplotlib` raises ImportError while healpy loads
    try:
        import healpy as hp
    finally:
        del sys.modules["matplotlib"]
    return hp
