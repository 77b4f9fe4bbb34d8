"""The background cube's layout: its variables and how it is cut into regions.

``background.zarr`` has dims (time, pixel, band): one float32 variable per component and the
total (``straylight.model.registry.component_names(total=True)``, e- s-1 pixel-1), and the
parts of :data:`CUBE_PART_VARIABLES`; ``observable``, ``violations`` and
``door_opening_deg`` on (time, pixel).  It is chunked one time block
(``campaign.time_block_hours``: :func:`cube_time_blocks`) x about ``footprint.pixel_block_size``
pixels (equal blocks: :func:`~straylight.cube.footprint.pixel_block_length`) x all bands.  A
time-series read of one pointing then touches one chunk per time block, and a whole-sky read at
one time one chunk per pixel block.  A region, the unit of work of the cube's workers, is one
such chunk: a time block x a pixel block.

The regions are written to three stores (:class:`CubeStores`): background.zarr, and the
observability and limits stores the cube's workers fill beside it
(:mod:`straylight.cube.store`).

This module imports nothing beyond the standard library at its top, so that a job can name its
stores and start its workers before it imports numpy and the model
(:func:`straylight.cube.executors.start_region_workers`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from straylight.config import Campaign
    from straylight.cube.footprint import Footprint

__all__ = [
    "CUBE_PART_VARIABLES",
    "ENVELOPE_END_VARIABLES",
    "is_envelope_end_part",
    "CUBE_PIXEL_VARIABLES",
    "LIMITS_REGION_VARIABLES",
    "OBSERVABILITY_ANGLES",
    "OBSERVABILITY_VARIABLES",
    "CubeStores",
    "cube_chunks",
    "cube_pixel_blocks",
    "cube_time_blocks",
    "pixel_block_size",
]

#: the cube's (time, pixel) variables
CUBE_PIXEL_VARIABLES = ("observable", "violations", "door_opening_deg")
#: observability.zarr's angles besides the cube's own (time, pixel) variables: the cube's
#: geometry computes them for every sample, so its workers write observability.zarr too
OBSERVABILITY_ANGLES = ("sun_angle_deg", "moon_angle_deg", "earth_limb_angle_deg")
#: observability.zarr's data variables (straylight.cube.products.observability_dataset)
OBSERVABILITY_VARIABLES = ("observable", "violations") + OBSERVABILITY_ANGLES + ("door_opening_deg",)
#: parts of a component the cube stores beside it, (time, pixel, band) e-/s/pix, where observable
#: (NaN elsewhere): the earthshine via the door, which the assumption envelope scales apart from
#: the direct earthshine (straylight.model.envelope; the direct part is the earthshine minus it)
CUBE_PART_VARIABLES = ("earthshine_door",)
#: the parts the envelope's calibrated members change, re-evaluated at each end and summed in
#: groups (``<group>_<end>``: straylight.model.envelope.MEMBER_GROUPS; NaN where not observable
#: or without members): a region's workers compute them for the ends' limits (limits.zarr's
#: pessimistic and optimistic depths); background.zarr does not keep them (its size)
ENVELOPE_END_VARIABLES = tuple(
    f"{group}_{end}" for end in ("optimistic", "pessimistic") for group in ("earthshine", "sun_moon")
)


def is_envelope_end_part(name: str) -> bool:
    """Whether a region's variable is one of the envelope's re-evaluated groups
    (:data:`ENVELOPE_END_VARIABLES`): not a model output, not stored."""
    return name in ENVELOPE_END_VARIABLES


#: limits.zarr's variables the cube's workers write, region by region
#: (:func:`straylight.cube.store.region_limits`): the limits, the observability, and the
#: limits at the assumption envelope's two ends and the depth budget's 16th and 84th percentiles
#: (NaN where not observable; kept in the work store for their per-pixel medians, left out of the
#: product)
LIMITS_REGION_VARIABLES = (
    "limiting_mag",
    "observable",
    "limiting_mag_pessimistic",
    "limiting_mag_optimistic",
    "limiting_mag_p16",
    "limiting_mag_p84",
)


def cube_time_blocks(campaign: Campaign, n_times: int) -> list[tuple[int, int]]:
    """The cube's time blocks over ``n_times`` samples of the campaign's cadence, (start, stop)
    sample indices of about ``campaign.time_block_hours`` each.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (its config's ``campaign.cadence_s``, s, and ``campaign.time_block_hours``,
        h, default 6).
    n_times : int
        Samples in the time grid.

    Returns
    -------
    list of tuple of int
        ``(start, stop)`` sample indices covering [0, n_times) in order.
    """
    from straylight.cube.timegrid import time_blocks

    c = campaign.settings.campaign
    return time_blocks(n_times, float(c.cadence_s), float(c.time_block_hours))


def pixel_block_size(campaign: Campaign) -> int:
    """The configured pixels per block (``footprint.pixel_block_size``); the blocks' actual length
    is :func:`~straylight.cube.footprint.pixel_block_length` of it.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.

    Returns
    -------
    int
        Pixels per block asked for (default 1024).
    """
    return int(campaign.settings.footprint.pixel_block_size)


def cube_pixel_blocks(campaign: Campaign, fp: Footprint) -> list[slice]:
    """The cube's pixel blocks: slices into the footprint's pixels, of equal length but the last.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    fp : Footprint
        The survey footprint.

    Returns
    -------
    list of slice
        Slices into ``fp.pixels``, covering them in order.
    """
    return [slice(a, b) for a, b in fp.blocks(pixel_block_size(campaign))]


def cube_chunks(campaign: Campaign, n_times: int, n_pixels: int) -> dict:
    """The cube's chunk sizes, ``{"time": ..., "pixel": ..., "band": ...}``, for ``n_times``
    samples at ``n_pixels`` footprint pixels: one time block x one pixel block x all bands.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    n_times : int
        Samples in the time grid (at least 1).
    n_pixels : int
        Pixels in the footprint.

    Returns
    -------
    dict of str to int
        Chunk length along ``time``, ``pixel`` and ``band``.
    """
    from straylight.cube.footprint import pixel_block_length

    tb = cube_time_blocks(campaign, n_times)
    t_chunk = tb[0][1] - tb[0][0]
    p_chunk = pixel_block_length(n_pixels, pixel_block_size(campaign))
    return {"time": t_chunk, "pixel": p_chunk, "band": len(campaign.bands)}


@dataclass(frozen=True)
class CubeStores:
    """Where the cube's regions are written: the cube's store (background.zarr), and the
    observability and limits stores its workers fill beside it (None: not written).

    Attributes
    ----------
    cube : str
        background.zarr's path.
    observability : str or None
        The observability work store's path; None: not written.
    limits : str or None
        The limits work store's path; None: not written.
    """

    cube: str
    observability: str | None = None
    limits: str | None = None

    @classmethod
    def of(cls, stores) -> CubeStores:
        """``stores`` if it is a CubeStores, else the cube's store at the path ``stores`` alone.

        Parameters
        ----------
        stores : CubeStores or str or path-like
            The stores, or background.zarr's path.

        Returns
        -------
        CubeStores
            The stores.
        """
        return stores if isinstance(stores, CubeStores) else cls(str(stores))

    def resolved(self) -> CubeStores:
        """The same stores at absolute paths: workers (other hosts, other working directories)
        need them.

        Returns
        -------
        CubeStores
            The same stores, paths absolute (symlinks resolved); None stays None.
        """

        def absolute(path):
            return str(Path(path).resolve()) if path else None

        return CubeStores(absolute(self.cube), absolute(self.observability), absolute(self.limits))

    def paths(self) -> tuple:
        """The stores' paths, the cube's first (None for a store not written).

        Returns
        -------
        tuple of (str or None)
            ``(cube, observability, limits)``.
        """
        return self.cube, self.observability, self.limits
