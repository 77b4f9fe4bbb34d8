"""The one way the background is evaluated at (time, pointing) samples: the observing geometry
(angles, constraints, the door) and every source's e-/s/pix in each band
(:func:`background_at`).  ``straylight sky``, ``sky --input``, :func:`straylight.sky_background`,
``straylight visibility`` (through the pointing tables) and the cube's regions all call it."""

from __future__ import annotations

import numpy as np

from straylight.model.result import BackgroundResult
from straylight.sky.frames import TelescopeFrame, telescope_frame
from straylight.sky.geometry import observing_geometry

__all__ = ["background_at", "background_result"]


def background_at(
    model,
    satellite_km,
    bodies_km: dict,
    los,
    bands,
    scene_index=None,
    stars=None,
    faint_rates: dict | None = None,
    runs=None,
    into: tuple | None = None,
    observable_only: bool = False,
    geometry_bodies: tuple = ("sun", "moon"),
) -> tuple[dict, dict]:
    """The observing geometry and the background at flat samples.

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model (its Earth radius and constraints give the geometry).
    satellite_km : ndarray, shape (m, 3)
        Geocentric ICRS satellite positions at the samples' m distinct times (scenes), km.
    bodies_km : dict of str to ndarray
        Body -> geocentric ICRS positions (m, 3), km: the Sun, the Moon and the planets the
        background counts.
    los : ndarray, shape (n, 3)
        Unit lines of sight, ICRS.
    bands : sequence of str
        Band names.
    scene_index : ndarray of int, shape (n,), or None
        Each sample's scene (row of ``satellite_km`` and ``bodies_km``); None: sample i at
        scene i (m = n).
    stars : StarTable or None
        The off-field stars (None: stars = 0).
    faint_rates : dict or None
        The faint stars' map at these lines of sight, band -> e-/s/pix (n,), when known.
    runs : SceneRuns or None
        The samples' scene runs when the caller knows them (e.g. a cube's time steps).
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

    def at(rows, sel=None):  # the scenes' rows at the samples (all, or those ``sel``)
        rows = np.asarray(rows, float)
        index = scene_index if sel is None or scene_index is None else np.take(scene_index, sel)
        index = sel if index is None else index
        return rows if index is None else np.take(rows, index, axis=0)

    sat, sun = at(satellite_km), at(bodies_km["sun"])
    frame = telescope_frame(los, sun - sat)  # once for the geometry and the background
    g = observing_geometry(
        sat,
        {b: sun if b == "sun" else at(bodies_km[b]) for b in geometry_bodies},
        los,
        campaign.earth.radius_km,
        campaign.constraints,
        frame=frame,
        runs=runs,
    )
    if not observable_only:
        return g, model.evaluate(
            sat,
            {b: sun if b == "sun" else at(v) for b, v in bodies_km.items()},
            los,
            g,
            bands,
            stars,
            faint_rates=faint_rates,
            frame=frame,
            into=into,
            runs=runs,
        )
    if into is None:
        raise ValueError("observable_only needs into: the array the observable samples are written to")
    names, values = into
    values[...] = np.nan
    sel = np.flatnonzero(g["observable"])
    if sel.size:
        # rows by index with np.take, faster than numpy's fancy indexing of (N, 3) rows
        sub = TelescopeFrame(*(np.take(a, sel, axis=0) for a in (frame.x, frame.y, frame.z)))
        part = np.empty((len(names), sel.size, len(bands)), values.dtype)
        model.evaluate(
            np.take(sat, sel, axis=0),
            {b: at(v, sel) for b, v in bodies_km.items()},
            np.take(los, sel, axis=0),
            {k: np.asarray(v)[sel] for k, v in g.items()},
            bands,
            stars,
            faint_rates=None if faint_rates is None else {b: v[sel] for b, v in faint_rates.items()},
            frame=sub,
            into=(names, part),
            runs=None if runs is None else runs.at(sel),
        )
        values[:, sel] = part
    return g, {}


def background_result(
    model,
    scene,
    los,
    bands,
    scene_index=None,
    stars=None,
    in_field_bands=None,
    geometry_bodies: tuple = ("sun", "moon"),
) -> BackgroundResult:
    """The background at flat samples as one :class:`~straylight.model.result.BackgroundResult`
    (:func:`background_at`'s geometry and components, the bands' zero points, the flags the
    sources report, and where asked the bodies inside the field).

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model.
    scene : Scene
        The m distinct times' satellite and bodies (:func:`~straylight.sky.observing.scene`),
        geocentric ICRS km.
    los : ndarray, shape (n, 3)
        Unit lines of sight, ICRS.
    bands : sequence of str
        Band names.
    scene_index : ndarray of int, shape (n,), or None
        Each sample's row of ``scene``; None: sample i at row i (m = n).
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
    g, comps = background_at(
        model,
        scene.satellite_km,
        scene.bodies_km,
        los,
        bands,
        scene_index=scene_index,
        stars=stars,
        geometry_bodies=geometry_bodies,
    )
    first = next(iter(comps.values()))
    in_field = {}
    if in_field_bands is not None:

        def rows(a):
            return np.asarray(a) if scene_index is None else np.asarray(a)[scene_index]

        bodies = {k: rows(v) for k, v in scene.bodies_km.items()}
        in_field = model.in_field.find(rows(scene.satellite_km), bodies, los, g, list(in_field_bands))
    return BackgroundResult(
        bands=tuple(bands),
        rates={b: {c: v for c, v in comps[b].items() if not c.startswith("_")} for b in bands},
        geometry=g,
        zero_points={b: model.sky_zero_point(b) for b in bands},
        flags={k[1:]: v for k, v in first.items() if k.startswith("_")},
        in_field=in_field,
    )
