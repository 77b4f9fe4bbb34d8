"""The one way the background is evaluated at (time, pointing) samples: the observing geometry
(angles, constraints, the door) and every source's e-/s/pix in each band
(:func:`background_at`).  ``straylight sky``, ``sky --input``, :func:`straylight.sky_background`,
``straylight visibility`` (through the pointing tables) and the cube's regions all call it."""

from __future__ import annotations

import numpy as np

from straylight.model.result import BackgroundResult
from straylight.model.samples import SampleBatch
from straylight.sky.geometry import observing_geometry

__all__ = ["background_at", "background_result"]


def background_at(
    model,
    samples: SampleBatch,
    bands,
    stars=None,
    into: tuple | None = None,
    observable_only: bool = False,
    geometry_bodies: tuple = ("sun", "moon"),
) -> tuple[dict, dict]:
    """The observing geometry and the background at a batch of samples.

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model (its Earth radius and constraints give the geometry).
    samples : SampleBatch
        The samples: their scene (the satellite, the Sun, the Moon and the planets the
        background counts), lines of sight, scene runs and faint stars' map where known.
    bands : sequence of str
        Band names.
    stars : StarTable or None
        The off-field stars (None: stars = 0).
    into : (sequence of str, ndarray) or None
        (component names, float array (names, n, bands)) that receives the components, as in
        :meth:`~straylight.model.background.BackgroundModel.evaluate`.
    observable_only : bool
        Evaluate the observable samples only; the others get NaN in every component (needs
        ``into``).
    geometry_bodies : tuple of str
        The bodies whose angles the geometry reports (the Sun and the Moon at least; the
        background finds the planets' own where they count).

    Returns
    -------
    geometry : dict
        :func:`~straylight.sky.geometry.observing_geometry`'s arrays (n,): angles in deg, the
        door opening (deg), the violation mask, ``observable``.
    components : dict
        :meth:`~straylight.model.background.BackgroundModel.evaluate`'s: band -> component ->
        e-/s/pix (n,); with ``observable_only``, an empty dict (the values are in ``into``).
    """
    campaign = model.campaign
    if observable_only and into is None:
        raise ValueError("observable_only needs into: the array the observable samples are written to")
    g = observing_geometry(
        samples.satellite_km,
        {b: samples.body_km(b) for b in geometry_bodies},
        samples.los,
        campaign.earth.radius_km,
        campaign.constraints,
        frame=samples.frame,  # once for the geometry and the background
        runs=samples.runs,
    )
    if not observable_only:
        return g, model.evaluate_samples(samples.source_samples(g, stars), bands, into)
    names, values = into
    values[...] = np.nan
    sel = np.flatnonzero(g["observable"])
    if sel.size:
        part = np.empty((len(names), sel.size, len(bands)), values.dtype)
        geometry = {k: np.asarray(v)[sel] for k, v in g.items()}
        model.evaluate_samples(samples.take(sel).source_samples(geometry, stars), bands, (names, part))
        values[:, sel] = part
    return g, {}


def background_result(
    model,
    samples: SampleBatch,
    bands,
    stars=None,
    in_field_bands=None,
    geometry_bodies: tuple = ("sun", "moon"),
) -> BackgroundResult:
    """The background at a batch of samples as one
    :class:`~straylight.model.result.BackgroundResult` (:func:`background_at`'s geometry and
    components, the bands' zero points, the flags the sources report, and where asked the bodies
    inside the field).

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model.
    samples : SampleBatch
        The samples (:meth:`~straylight.model.samples.SampleBatch.at_times`).
    bands : sequence of str
        Band names.
    stars : StarTable or None
        The off-field stars (None: stars = 0).
    in_field_bands : sequence of str or None
        Look for the Sun, the Moon and the planets inside the field, with their AB magnitudes
        in these bands (an empty list: their V magnitudes only); None: not looked for.
    geometry_bodies : tuple of str
        The bodies whose angles the geometry reports (:func:`background_at`).

    Returns
    -------
    BackgroundResult
        Without times, pointing or limits (the caller's to give).
    """
    g, comps = background_at(model, samples, bands, stars, geometry_bodies=geometry_bodies)
    first = next(iter(comps.values()))
    in_field = {}
    if in_field_bands is not None:
        in_field = model.in_field.find(
            samples.satellite_km, samples.bodies_km, samples.los, g, list(in_field_bands)
        )
    return BackgroundResult(
        bands=tuple(bands),
        rates={b: {c: v for c, v in comps[b].items() if not c.startswith("_")} for b in bands},
        geometry=g,
        zero_points={b: model.sky_zero_point(b) for b in bands},
        flags={k[1:]: v for k, v in first.items() if k.startswith("_")},
        in_field=in_field,
    )
