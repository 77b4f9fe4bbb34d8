"""Off-field stars (paper sect. 2.2): the catalog's stars brighter than stars.offfield_mag_limit
summed one by one through the exact transfer (Earth, door, PST(theta, phi)), and the fainter ones
as a smoothed map (the spherical convolution of their fluxes with the azimuth-averaged PST,
evaluated at each line of sight; no Earth or door blocking).

:class:`OffFieldStars` adds the two: the direct stars' pairs
(:class:`~straylight.sources.stars_direct.DirectStarPairs`, skipped on a bound per HEALPix sky
cell and floor level) and the faint stars' map
(:class:`~straylight.sources.stars_faint.FaintStarMap`); the star table and its loading are in
:mod:`straylight.sources.stars_table`."""

from __future__ import annotations

import numpy as np

from straylight.sources.context import Samples, SourceContext
from straylight.sources.rates import BandRates
from straylight.sources.stars_direct import DirectStarPairs
from straylight.sources.stars_faint import FaintStarMap
from straylight.sources.stars_table import StarTable

__all__ = ["OffFieldStars"]


class OffFieldStars(DirectStarPairs, FaintStarMap):
    """The off-field stars' e-/s/pix per band (:meth:`rates`): the direct stars' (sample, star)
    pairs that count (:meth:`pairs`) and the faint stars' map (:meth:`faint_star_rates`).  The
    skip's knobs are class attributes (a test may set them).

    Parameters
    ----------
    context : SourceContext
        The campaign's instrument as the sources see it.
    policy : FidelityPolicy
        The fidelity policy (tolerance and the stars_skip share).
    """

    def __init__(self, context: SourceContext, policy):
        self.context, self.policy = context, policy

    def rates(self, samples: Samples, bands) -> BandRates:
        """The stars' e-/s/pix per band, (bands, samples flattened): ``samples.stars``' direct
        pairs (skipped per sky cell against ``samples.floor_ratio``), then the faint map
        (``samples.faint_rates`` when already computed; else computed here); zeros without stars.

        Parameters
        ----------
        samples : Samples
            The batch of (time, pointing) samples (reads ``stars``, ``faint_rates``,
            ``floor_ratio``, ``frame``, the satellite, the door and ``runs``).
        bands : sequence of str
            Band names of the instrument (a band missing from the star table's
            magnitudes gets no direct stars).

        Returns
        -------
        BandRates
            ``per_band["stars"]``: ndarray, shape (bands, samples flattened), e-/s/pix.
        """
        stars_e = self.e_per_s(samples, samples.stars, bands, samples.floor_ratio, samples.faint_rates)
        return BandRates(per_band={"stars": stars_e})

    def e_per_s(
        self, samples: Samples, stars: StarTable | None, bands, floor_ratio, faint_rates: dict | None = None
    ) -> np.ndarray:
        """:meth:`rates`' array from its inputs: (bands, samples flattened) e-/s/pix.

        Parameters
        ----------
        samples : Samples
            The batch of samples (reads ``frame``, the satellite, the door and ``runs``).
        stars : StarTable or None
            The off-field stars; None: no stars (zeros, unless ``faint_rates`` is given).
        bands : sequence of str
            Band names.
        floor_ratio : float or ndarray
            Each sample's floor over the darkest zodiacal light, >= 1 (the direct stars' skip).
        faint_rates : dict of str to ndarray, optional
            Band -> the faint stars' e-/s/pix at the samples' lines of sight, already computed;
            None: computed here when ``stars`` has faint stars.

        Returns
        -------
        ndarray, shape (len(bands), samples flattened)
            e-/s/pix.
        """
        shape = samples.shape
        star_pairs = (
            self.pairs(
                stars, samples.frame, samples.satellite_km, samples.door_deg, floor_ratio, samples.runs
            )
            if stars is not None and len(stars.ra_deg)
            else None
        )  # once for all bands
        faint = faint_rates
        if faint is None and stars is not None and len(stars.faint_ra_deg):
            faint = self.faint_star_rates(stars, samples.frame.z, bands)
        n = int(np.prod(shape))
        stars_e = np.zeros((len(bands), n))
        for ib, name in enumerate(bands):
            if star_pairs is not None and name in stars.mag_ab:
                pairs_shape, (pair_sample, pair_star, pair_transfer) = star_pairs
                flux = self.context.photometry(name).from_ab(stars.mag_ab[name])
                stars_e[ib] = np.bincount(pair_sample, weights=pair_transfer * flux[pair_star], minlength=n)
            if faint is not None and name in faint:
                stars_e[ib] += np.broadcast_to(faint[name], shape).ravel()
        return stars_e
