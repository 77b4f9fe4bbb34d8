"""straylight: stray-light and sky-background products for the China Space Station Telescope.

Public API (small on purpose):

* :func:`sky_background` - background components, total, 5-sigma depth and observability of any
  (astropy ``Time``, ``SkyCoord``), as an astropy ``QTable`` with units.
* :func:`open_campaign` - a finished campaign's products as xarray objects.
* :func:`load_campaign` - a validated campaign config with its orbit, Earth model, constraints.
* :class:`DE405` - the JPL DE405 ephemeris, vectorised over times.
* :func:`scene`, :func:`sample_geometry` - positions and the observing geometry of samples.
"""
from straylight._version import __version__
from straylight.api import CampaignProducts, open_campaign, sky_background
from straylight.config import Campaign, load_campaign
from straylight.sky.ephemeris import BODIES, DE405
from straylight.errors import ConfigError, EphemerisRangeError, InputError, StraylightError
from straylight.sky.observing import sample_geometry, scene
from straylight.sky.timeutil import configure_offline

configure_offline()

__all__ = [
    "BODIES", "DE405", "Campaign", "CampaignProducts", "ConfigError", "EphemerisRangeError", "InputError",
    "StraylightError", "load_campaign", "open_campaign", "sample_geometry", "scene",
    "sky_background",
]
