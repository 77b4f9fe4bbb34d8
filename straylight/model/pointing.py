"""The one way the background is evaluated at (time, pointing) samples: the observing geometry
(angles, constraints, the door) and every source's e-/s/pix in each band
(:func:`background_at`).  ``straylight sky``, ``sky --input``, :func:`straylight.sky_background`,
``straylight visibility`` (through the pointing tables) and the cube's regions all call it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from straylight.model.result import BackgroundResult
from straylight.model.samples import SampleBatch
from straylight.sky.geometry import observing_geometry

__all__ = ["background_at", "background_result", "sample_geometry"]


def background_at(
    model,
    samples: SampleBatch,
    bands,
    stars=None,
    into: tuple | None = None,
    observable_only: bool = False,
    geometry_bodies: tuple = ("sun", "moon"),
) -> BackgroundResult:
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
        :meth:`~straylight.model.background.BackgroundModel.evaluate` (the result's rates are
        its views, of those components only).
    observable_only : bool
        Evaluate the observable samples only; the others get NaN in every component and False
        in every flag (needs ``into``).
    geometry_bodies : tuple of str
        The bodies whose angles the geometry reports (the Sun and the Moon at least; the
        background finds the planets' own where they count).

    Returns
    -------
    BackgroundResult
        The geometry (:func:`~straylight.sky.geometry.observing_geometry`'s arrays (n,):
        angles in deg, the door opening (deg), the violation mask, ``observable``), the rates
        (band -> component -> e-/s/pix (n,)), the flags the sources report and the bands'
        zero points; without times, pointing, limits or bodies in the field.
    """
    if observable_only and into is None:
        raise ValueError("observable_only needs into: the array the observable samples are written to")
    g = sample_geometry(model, samples, geometry_bodies)
    if not observable_only:
        return _result(model, bands, g, model.evaluate_samples(samples.source_samples(g, stars), bands, into))
    names, values = into
    values[...] = np.nan
    sel = np.flatnonzero(g["observable"])
    flags = {}
    if sel.size:
        part = np.empty((len(names), sel.size, len(bands)), values.dtype)
        geometry = {k: np.asarray(v)[sel] for k, v in g.items()}
        comps = model.evaluate_samples(
            samples.take(sel).source_samples(geometry, stars), bands, (names, part)
        )
        values[:, sel] = part
        flags = {k: _scattered(v, sel, samples.n) for k, v in _flags(comps[bands[0]]).items()}
    rates = {b: {c: values[k, :, ib] for k, c in enumerate(names)} for ib, b in enumerate(bands)}
    return BackgroundResult(tuple(bands), rates, g, model.sky_zero_points(bands), flags=flags)


def sample_geometry(model, samples: SampleBatch, bodies: tuple = ("sun", "moon")) -> dict:
    """The observing geometry of a batch of samples under the model's Earth and constraints
    (:func:`~straylight.sky.geometry.observing_geometry`), the telescope frame the samples'
    own (computed once for the geometry and the background).

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model (its Earth radius and constraints).
    samples : SampleBatch
        The samples.
    bodies : tuple of str
        The bodies whose angles the geometry reports (the Sun and the Moon at least).

    Returns
    -------
    dict
        observing_geometry's arrays (n,): angles in deg, the door opening (deg), the violation
        mask, ``observable``.
    """
    campaign = model.campaign
    return observing_geometry(
        samples.satellite_km,
        {b: samples.body_km(b) for b in bodies},
        samples.los,
        campaign.earth.radius_km,
        campaign.constraints,
        frame=samples.frame,
        runs=samples.runs,
    )


def _flags(components: dict) -> dict:
    """The flags among a band's :meth:`~straylight.model.background.BackgroundModel.evaluate`
    entries (``_<flag>``), by name."""
    return {k[1:]: v for k, v in components.items() if k.startswith("_")}


def _scattered(values, sel: np.ndarray, n: int) -> np.ndarray:
    """A flag at samples ``sel`` on all ``n`` samples (False elsewhere)."""
    out = np.zeros(n, bool)
    out[sel] = values
    return out


def _result(model, bands, geometry: dict, comps: dict) -> BackgroundResult:
    """The :class:`~straylight.model.result.BackgroundResult` of an evaluation's ``comps``
    (:meth:`~straylight.model.background.BackgroundModel.evaluate`'s) at samples of
    ``geometry``."""
    return BackgroundResult(
        bands=tuple(bands),
        rates={b: {c: v for c, v in comps[b].items() if not c.startswith("_")} for b in bands},
        geometry=geometry,
        zero_points=model.sky_zero_points(bands),
        flags=_flags(comps[bands[0]]),
    )


def background_result(
    model,
    samples: SampleBatch,
    bands,
    stars=None,
    in_field_bands=None,
    geometry_bodies: tuple = ("sun", "moon"),
) -> BackgroundResult:
    """:func:`background_at`'s result, and where asked the bodies inside the field.

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
    result = background_at(model, samples, bands, stars, geometry_bodies=geometry_bodies)
    if in_field_bands is None:
        return result
    in_field = model.in_field.find(
        samples.satellite_km, samples.bodies_km, samples.los, result.geometry, list(in_field_bands)
    )
    return replace(result, in_field=in_field)
