"""The background model (:class:`BackgroundModel`: each source's e-/s/pixel per band, added) and
its fidelity policy (:class:`FidelityPolicy`: the tolerance, its shares, the fast paths).

Internal: not part of the public API (``straylight.__all__``; users evaluate the model through
:class:`straylight.SkyModel`).  ``__all__`` below names what the layers above it use.

Imports ``straylight.sources``, ``straylight.sky`` and ``straylight.config`` (the layers below it:
docs/architecture.md); never the layers above it (``storage``, ``limits``, ``cube``, ``planning``).
"""

from straylight.model import registry
from straylight.model.background import BackgroundModel
from straylight.model.fidelity import (
    ERROR_BUDGET_SHARES,
    LUT_BUILD_SECONDS_PER_NODE,
    LUT_SAVED_SECONDS_PER_SAMPLE,
    MOONLIT_LUT_BUILD_SECONDS_PER_NODE,
    FidelityPolicy,
    unobservable_samples,
)

__all__ = [
    "BackgroundModel",
    "ERROR_BUDGET_SHARES",
    "FidelityPolicy",
    "LUT_BUILD_SECONDS_PER_NODE",
    "LUT_SAVED_SECONDS_PER_SAMPLE",
    "MOONLIT_LUT_BUILD_SECONDS_PER_NODE",
    "registry",
    "unobservable_samples",
]
