"""What every source of light returns: :class:`BandRates`, its e-/s/pixel in each band for a
batch of samples, and the lamps the solar-spectrum sources are lit by.

A source's rate in a product part (e.g. ``moon``, ``earthshine_direct``) is written in two
forms the background model adds in a fixed order:

- ``per_band``: e-/s/pix per band, an array (bands, samples), for sources with their own
  spectrum (zodiacal light, stars);
- ``per_lamp``: band-independent coefficients, e-/s/pix per photon s-1 m-2 of a lamp, for
  sources lit by the Sun (directly, via the Moon or via the Earth).  In band ``b`` a lamp gives
  ``sun_at_1au[b] * scale`` photons s-1 m-2, :data:`LAMPS` below; the model multiplies and adds
  them in one compiled pass, so the sum's order, and its bits, do not depend on the batch.

Coefficients of several sources for the same part and lamp are added before the product (the
moonlit Earth's to the sunlit Earth's in-field Moon term), in registry order.  A part whose
light is not the lamp's spectrum (the Earth's, reflected with its spectral albedo) gives a
per-band factor on its lamp terms, ``band_factors``: in band ``b`` its coefficient is worth
``sun_at_1au[b] * band_factors[part][b] * scale``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["LAMPS", "BandRates"]

#: The lamps of the solar-spectrum sources, in the order their terms are added.  Each is the
#: Sun's photon irradiance at 1 AU in a band times a per-sample scale (dimensionless):
#: ``sun``: (1 AU / Sun-satellite distance)^2, the Sun at the satellite;
#: ``sun_at_1au``: 1 (the Moon's and planets' coefficients carry their fraction of the Sun);
#: ``moon_at_earth``: the Moon's irradiance at the Earth as a fraction of the Sun's at 1 AU
#: (eclipse included), the moonlit Earth's lamp.
LAMPS = ("sun", "sun_at_1au", "moon_at_earth")


@dataclass
class BandRates:
    """One source's e-/s/pix for a batch of samples (see the module's docstring).

    Attributes
    ----------
    per_band : dict of str to ndarray
        Product part -> e-/s/pix, float64 array (bands, samples flattened).
    per_lamp : dict of str to dict of str to ndarray
        Product part -> lamp (one of :data:`LAMPS`) -> coefficient, e-/s/pix per photon
        s-1 m-2 of that lamp, float64 array broadcastable to the samples' shape.
    extras : dict of str to ndarray
        Per-sample flags the source reports beside its rates (e.g. the zodiacal light's
        ``zodiacal_no_data``), of the samples' shape; the model passes them on as ``_<key>``.
    band_factors : dict of str to ndarray
        Product part -> factor (bands,) on its ``per_lamp`` terms in each band, dimensionless
        (a part absent: 1); every source adding to a part gives it the same factors.
    """

    per_band: dict = field(default_factory=dict)
    per_lamp: dict = field(default_factory=dict)
    extras: dict = field(default_factory=dict)
    band_factors: dict = field(default_factory=dict)

    def e_per_s(self, part: str, bands_sun_at_1au: np.ndarray, lamp_scales: dict, shape: tuple) -> np.ndarray:
        """Part ``part``'s e-/s/pix, (bands, samples flattened), from both forms.

        Parameters
        ----------
        part : str
            The product part.
        bands_sun_at_1au : ndarray, shape (bands,)
            Each band's solar photon irradiance at 1 AU, photons s-1 m-2.
        lamp_scales : dict of str to ndarray
            Lamp -> per-sample scale (dimensionless), broadcastable to ``shape``.
        shape : tuple
            The samples' shape.

        Returns
        -------
        ndarray, shape (bands, prod(shape))
            e-/s/pix (zeros where the source gives nothing to ``part``).
        """
        n = int(np.prod(shape))
        s1 = np.asarray(bands_sun_at_1au, float)[:, None]
        if part in self.band_factors:
            s1 = s1 * np.asarray(self.band_factors[part], float)[:, None]
        out = np.zeros((s1.shape[0], n))
        if part in self.per_band:
            out += self.per_band[part]
        for lamp, coeff in self.per_lamp.get(part, {}).items():
            scale = np.broadcast_to(np.asarray(lamp_scales[lamp], float), shape).ravel()
            out += np.broadcast_to(np.asarray(coeff, float), shape).ravel() * (s1 * scale)
        return out
