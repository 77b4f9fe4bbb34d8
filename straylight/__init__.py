"""straylight: stray-light and sky-background products for the China Space Station Telescope.

Public API (small on purpose):

* :func:`load_campaign` - a validated campaign config with its orbit, Earth model, constraints.
* :class:`DE405` - the JPL DE405 ephemeris, vectorised over times.
* :func:`scene`, :func:`sample_geometry` - positions and the observing geometry of samples.
"""
from .config import Campaign, load_campaign
from .ephemeris import BODIES, DE405
from .errors import ConfigError, EphemerisRangeError, InputError, StraylightError
from .sky import sample_geometry, scene
from .timeutil import configure_offline

configure_offline()

__version__ = "0.1.0"
__all__ = [
    "BODIES", "DE405", "Campaign", "ConfigError", "EphemerisRangeError", "InputError",
    "StraylightError", "load_campaign", "sample_geometry", "scene",
]
