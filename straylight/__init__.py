"""straylight: stray-light and sky-background products for the China Space Station Telescope.

Public API (small on purpose):

* :func:`sky_background` - background components, total, 5-sigma depth and observability of any
  (astropy ``Time``, ``SkyCoord``), as an astropy ``QTable`` with units;
  :func:`violation_names` gives the names of its ``violations`` bit mask.
* :class:`SkyModel` - the same from a model built once, for a scheduler's loop
  (``SkyModel(config).background(time, coord, bands)``).
* :func:`open_campaign` - a finished campaign's products as xarray objects.
* :class:`SkyMaps` - a finished campaign's compact sky (``sky_compact.zarr``): full-sky maps and
  batches of (time, pixel) magnitudes and observability at memory speed, for schedulers.
* :func:`load_campaign` - a validated campaign config with its orbit, Earth model, constraints.
* :class:`DE405` - the JPL DE405 ephemeris, vectorised over times.
* :func:`scene`, :func:`sample_geometry` - positions and the observing geometry of samples.
* the errors: :class:`StraylightError` (a user's mistake, its message naming the file, field and
  value) and its kinds :class:`ConfigError`, :class:`InputError`, :class:`EphemerisRangeError`,
  :class:`OutputError`.

These names (``__all__``) are the public surface, documented in the API reference (docs/api/).
The sub-packages and modules are internal and may change between releases, with one exception:
``straylight.config``, whose ``__all__`` names the loading functions and typed settings a
program may use.  ``straylight.cli`` is the command line's (``straylight --help``).

The names are imported when first used (PEP 562), so a process that needs one module of the
package (a pipeline step, a worker) does not import astropy, numba and xarray for the others.
"""

from importlib import import_module

from straylight._version import __version__ as __version__
from straylight.errors import ConfigError as ConfigError
from straylight.errors import EphemerisRangeError as EphemerisRangeError
from straylight.errors import InputError as InputError
from straylight.errors import OutputError as OutputError
from straylight.errors import StraylightError as StraylightError

#: public name -> the module that defines it
_LAZY = {
    "CampaignProducts": "straylight.api",
    "open_campaign": "straylight.api",
    "sky_background": "straylight.api",
    "violation_names": "straylight.api",
    "SkyModel": "straylight.skymodel",
    "SkyMaps": "straylight.cube.skymaps",
    "Campaign": "straylight.config",
    "load_campaign": "straylight.config",
    "BODIES": "straylight.sky.ephemeris",
    "DE405": "straylight.sky.ephemeris",
    "sample_geometry": "straylight.sky.observing",
    "scene": "straylight.sky.observing",
}

__all__ = sorted(
    ["ConfigError", "EphemerisRangeError", "InputError", "OutputError", "StraylightError", *_LAZY]
)


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'straylight' has no attribute {name!r}")
    value = getattr(import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list:
    return sorted(set(globals()) | set(_LAZY))
