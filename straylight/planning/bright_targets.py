"""Targets that are bright stars: ``straylight visibility`` reports the sky's background and depth
at a pointing, which say nothing of a star sitting there; a target on a Hipparcos star is said so.

The stars are the Hipparcos new reduction's (van Leeuwen 2007, ``hip2.dat``, the default
catalog's source, :mod:`straylight.catalog.hipparcos`), carried to the campaign's epoch by their
proper motions; every one of them (V < ~12) is more than ten magnitudes brighter than the
survey's depth (~26 mag).
"""

from __future__ import annotations

import functools
import logging

import numpy as np

__all__ = ["MATCH_RADIUS_ARCSEC", "bright_stars_at", "warn_bright_targets"]

#: A target within this angle of a Hipparcos star (at the campaign's epoch) is on that star: a
#: target given at a catalogue's J2000 position stays within it for all but the fastest stars
#: (Sirius moved 35 arcsec in 2000-2026), and the star's halo reaches this far anyway.
MATCH_RADIUS_ARCSEC = 60.0


@functools.lru_cache(maxsize=1)
def _hipparcos():
    """(hip, ra, dec, pmra, pmdec, V) of the Hipparcos stars, read once per process."""
    from straylight.catalog.hipparcos import V_MINUS_HP_VERIFIED_BV, read_hip2, v_minus_hp

    h = read_hip2()
    v = h["hp_mag"] + v_minus_hp(np.clip(h["b_v_mag"], *V_MINUS_HP_VERIFIED_BV))
    return h["hip"], h["ra_deg"], h["dec_deg"], h["pmra_mas_yr"], h["pmdec_mas_yr"], v


def bright_stars_at(ra_deg, dec_deg, epoch_yr: float) -> list[dict]:
    """The Hipparcos star each target sits on (within :data:`MATCH_RADIUS_ARCSEC` at
    ``epoch_yr``), brightest first where several are near.

    Parameters
    ----------
    ra_deg, dec_deg : array_like, shape (m,)
        The targets' ICRS position, deg.
    epoch_yr : float
        The epoch the stars are carried to (Julian year, e.g. the campaign's start).

    Returns
    -------
    list of dict
        One per target on a star: ``index`` (the target's), ``hip``, ``v_mag`` (Johnson V,
        from Hp and B - V) and ``separation_arcsec``.
    """
    from straylight.catalog.hipparcos import HIPPARCOS_EPOCH_YR
    from straylight.catalog.star_table import propagate_positions

    hip, ra, dec, pmra, pmdec, v = _hipparcos()
    ra_t, dec_t = propagate_positions(ra, dec, pmra, pmdec, HIPPARCOS_EPOCH_YR, epoch_yr)
    star = _unit(ra_t, dec_t)
    out = []
    cos_r = np.cos(np.radians(MATCH_RADIUS_ARCSEC / 3600.0))
    for i, (a, d) in enumerate(zip(np.atleast_1d(ra_deg), np.atleast_1d(dec_deg))):
        c = star @ _unit(np.array([a]), np.array([d]))[0]
        near = np.flatnonzero(c >= cos_r)
        if near.size:
            j = near[np.argmin(v[near])]
            sep = np.degrees(np.arccos(np.clip(c[j], -1.0, 1.0))) * 3600.0
            out.append(
                {"index": i, "hip": int(hip[j]), "v_mag": float(v[j]), "separation_arcsec": float(sep)}
            )
    return out


def _unit(ra_deg, dec_deg) -> np.ndarray:
    ra, dec = np.radians(np.asarray(ra_deg, float)), np.radians(np.asarray(dec_deg, float))
    return np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], axis=-1)


def warn_bright_targets(ra_deg, dec_deg, epoch, names=None) -> list[str]:
    """Warn (one logged line each) for every target that is a Hipparcos star: its background and
    depth are the sky's around the star, not the star's own light.  Returns the warnings.

    Parameters
    ----------
    ra_deg, dec_deg : array_like, shape (m,)
        The targets' ICRS position, deg.
    epoch : float or str
        The campaign's epoch: a Julian year, or a UTC time (ISO 8601 text, e.g. its start).
    names : list of str, optional
        The targets' names, for the messages (default: their positions).

    Returns
    -------
    list of str
        The warnings given.
    """
    if isinstance(epoch, str):
        from straylight.sky.timeutil import parse_utc, quiet_dubious_years

        with quiet_dubious_years():
            epoch = float(parse_utc(epoch, "start").jyear)
    ra_deg, dec_deg = np.atleast_1d(ra_deg), np.atleast_1d(dec_deg)
    lines = []
    for hit in bright_stars_at(ra_deg, dec_deg, float(epoch)):
        i = hit["index"]
        who = names[i] if names is not None else f"RA {ra_deg[i]:.4f} Dec {dec_deg[i]:+.4f}"
        lines.append(
            f"{who}: on the star HIP {hit['hip']} (V = {hit['v_mag']:.2f}, "
            f"{hit['separation_arcsec']:.1f} arcsec away): "
            "the background and 5-sigma limits are the sky's at that pointing, without the star's own "
            "light, which is far brighter than the survey's depth"
        )
    for line in lines:
        logging.getLogger(__name__).warning("warning: %s", line)
    return lines
