"""Pipeline products built from a campaign (the library side of the Snakemake rules).

* :func:`ephemeris_dataset` - the campaign time grid with body and satellite positions and the
  Sun/Moon geometry, written as ``ephemeris.zarr``.
* :func:`footprint_products` - the footprint HEALPix mask and the work plan (pixel blocks by
  time blocks).
* :func:`observability_dataset` - (time, pixel) observability, violated-constraint flags and
  the main angles over the footprint.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from straylight.config import Campaign
from straylight.cube.footprint import Footprint, footprint_from_config
from straylight.cube.timegrid import time_blocks
from straylight.sky.ephemeris import BODIES
from straylight.sky.geometry import moon_phase, observing_geometry, violation_mask_attrs
from straylight.sky.limb import earth_blocks
from straylight.sky.observing import scene
from straylight.sky.vectors import radec_to_unit

__all__ = ["ephemeris_dataset", "footprint_products", "write_footprint_fits", "observability_dataset"]


def _var(data, dims, units, long_name, **extra):
    attrs = {"units": units, "long_name": long_name}
    attrs.update(extra)
    return xr.Variable(dims, data, attrs)


def ephemeris_dataset(campaign: Campaign) -> xr.Dataset:
    """The campaign's time grid with DE405 body positions and the satellite's orbit.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (times, orbit, Earth).

    Returns
    -------
    xarray.Dataset
        ephemeris.zarr's dataset over n_time UTC samples: ``body_position_km`` (time, body,
        xyz) and ``satellite_position_km`` (time, xyz), geocentric km; ``jd_tdb`` (d);
        ``moon_phase_angle_deg``, ``moon_elongation_deg``, ``earth_angular_radius_deg`` (deg);
        ``moon_illuminated_fraction``, ``sun_moon_distance_ratio`` (1);
        ``satellite_in_earth_shadow`` (bool); coordinates ``time`` (UTC datetime64), ``body``
        (:data:`straylight.sky.ephemeris.BODIES`), ``xyz``.
    """
    t = campaign.times
    sc = scene(campaign.orbit, t)
    sat = sc.satellite_km
    sun, moon = sc.bodies_km["sun"], sc.bodies_km["moon"]
    body_pos = np.stack([sc.bodies_km[b] for b in BODIES], axis=1)
    alpha, fraction, elongation = moon_phase(sun, moon, sat)
    in_shadow = earth_blocks(sat, sun - sat, campaign.earth.radius_km)
    r = np.linalg.norm(sat, axis=-1)
    ds = xr.Dataset(
        {
            "body_position_km": _var(
                body_pos,
                ("time", "body", "xyz"),
                "km",
                "geocentric geometric position, ICRS axes (JPL DE405)",
            ),
            "satellite_position_km": _var(sat, ("time", "xyz"), "km", "satellite position, GCRS axes"),
            "jd_tdb": _var(np.asarray(t.tdb.jd, dtype=float), ("time",), "d", "Julian date, TDB"),
            "moon_phase_angle_deg": _var(
                alpha, ("time",), "deg", "lunar phase angle Sun-Moon-satellite (0 = full)"
            ),
            "moon_illuminated_fraction": _var(
                fraction, ("time",), "1", "illuminated fraction of the lunar disc (1 + cos alpha) / 2"
            ),
            "moon_elongation_deg": _var(
                elongation, ("time",), "deg", "Sun-satellite-Moon angle (180 = full Moon)"
            ),
            "sun_moon_distance_ratio": _var(
                np.linalg.norm(moon - sat, axis=-1) / np.linalg.norm(sun - sat, axis=-1),
                ("time",),
                "1",
                "Moon distance over Sun distance from the satellite",
            ),
            "satellite_in_earth_shadow": _var(
                in_shadow, ("time",), "1", "Sun hidden by the Earth from the satellite (two-condition test)"
            ),
            "earth_angular_radius_deg": _var(
                np.degrees(np.arcsin(campaign.earth.radius_km / r)),
                ("time",),
                "deg",
                "angular radius of the Earth seen from the satellite",
            ),
        },
        coords={
            "time": ("time", t.datetime64, {"long_name": "UTC sample time"}),
            # object arrays: Zarr v3's variable-length `string` type, as the other products' labels
            # (numpy's fixed-width "<U" is zarr-python's FixedLengthUTF32, outside the v3 spec)
            "body": ("body", np.array(BODIES, dtype=object)),
            "xyz": ("xyz", np.array(["x", "y", "z"], dtype=object)),
        },
        attrs={
            "campaign": campaign.name,
            "ephemeris": "JPL DE405 (PyPI de405), Chebyshev evaluation by straylight.sky.ephemeris",
            "orbit_model": campaign.orbit_settings.model,
            "cadence_s": float(campaign.settings.campaign.cadence_s),
        },
    )
    return ds


def footprint_products(campaign: Campaign) -> tuple[Footprint, dict]:
    """The footprint and the work plan (pixel blocks by time blocks) as a JSON-able dict.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (footprint section, times, time and pixel block sizes).

    Returns
    -------
    fp : Footprint
        The footprint.
    plan : dict
        ``campaign``, ``nside``, ``ordering``, ``frame``, ``n_pixels``, ``area_deg2`` (deg2),
        ``n_times``, ``n_samples``, ``time_blocks`` and ``pixel_blocks`` (lists of
        ``[start, stop]`` indices).

    Raises
    ------
    ConfigError, InputError
        As :func:`~straylight.cube.footprint.footprint_from_config`.
    """
    fp = footprint_from_config(campaign.settings.footprint, campaign.path.parent)
    c = campaign.settings.campaign
    t_blocks = time_blocks(len(campaign.times), c.cadence_s, float(c.time_block_hours))
    p_blocks = fp.blocks(campaign.settings.footprint.pixel_block_size)
    plan = {
        "campaign": campaign.name,
        "nside": fp.nside,
        "ordering": fp.ordering,
        "frame": "icrs",
        "n_pixels": int(fp.pixels.size),
        "area_deg2": fp.area_deg2,
        "n_times": len(campaign.times),
        "n_samples": int(fp.pixels.size * len(campaign.times)),
        "time_blocks": [list(b) for b in t_blocks],
        "pixel_blocks": [list(b) for b in p_blocks],
    }
    return fp, plan


def write_footprint_fits(fp: Footprint, path) -> None:
    """The footprint as a HEALPix FITS map (1 inside, 0 outside), readable by healpy.

    Parameters
    ----------
    fp : Footprint
        The footprint (its nside and ordering are the map's; ICRS).
    path : str or path-like
        FITS file to write (replaced atomically).
    """
    from straylight.util.healpix import healpy
    from straylight.util.io import atomic_path

    hp = healpy()

    m = np.zeros(hp.nside2npix(fp.nside), dtype=np.float32)
    m[fp.pixels] = 1.0
    with atomic_path(path) as tmp:
        hp.write_map(
            str(tmp),
            m,
            nest=fp.nest,
            coord="C",
            column_names=["FOOTPRINT"],
            column_units=["1"],
            dtype=np.float32,
            overwrite=True,
        )


def _observability_from(g: dict, ephem: xr.Dataset, fp: Footprint, campaign: Campaign) -> xr.Dataset:
    """observability.zarr's dataset from its (time, pixel) arrays ``g``, with its coordinates and
    attributes."""
    ds = xr.Dataset(
        {
            "observable": _var(
                g["observable"], ("time", "pixel"), "1", "pointing satisfies every constraint"
            ),
            "violations": xr.Variable(("time", "pixel"), g["violations"], violation_mask_attrs()),
            "sun_angle_deg": _var(g["sun_angle_deg"], ("time", "pixel"), "deg", "angle LOS-Sun"),
            "moon_angle_deg": _var(g["moon_angle_deg"], ("time", "pixel"), "deg", "angle LOS-Moon"),
            "earth_limb_angle_deg": _var(
                g["earth_limb_angle_deg"], ("time", "pixel"), "deg", "LOS elevation above the Earth limb"
            ),
            "door_opening_deg": _var(
                g["door_opening_deg"],
                ("time", "pixel"),
                "deg",
                "aperture door opening (0 = no allowed state)",
            ),
        },
        coords={
            "time": ephem["time"],
            "pixel": ("pixel", fp.pixels, {"long_name": "HEALPix pixel index"}),
            "ra_deg": ("pixel", fp.ra_deg, {"units": "deg", "long_name": "ICRS RA of pixel centre"}),
            "dec_deg": ("pixel", fp.dec_deg, {"units": "deg", "long_name": "ICRS Dec of pixel centre"}),
        },
        attrs={
            "healpix_nside": fp.nside,
            "healpix_ordering": fp.ordering.upper(),
            "healpix_frame": "ICRS",
            "campaign": campaign.name,
        },
    )
    return ds


def _chunked_arrays(geometry, dtypes: dict, edges: tuple, token: str) -> dict:
    """Lazy (time, pixel) dask arrays, one per ``dtypes`` key, whose chunks (``edges``: time and
    pixel chunk edges) are ``geometry(time slice, pixel slice)[key]``, each chunk's geometry
    computed once for all the keys.  One graph built directly: a geometry task per chunk (its
    key from ``token``, one token of the product's inputs, and the chunk's indices) and per
    variable a getitem of it.  Delayed calls, from_delayed and block per chunk cost more to
    build than the chunks to compute."""
    import operator

    import dask.array as da
    from dask.highlevelgraph import HighLevelGraph

    t_edges, p_edges = edges
    blocks = [
        ((i, j), slice(t0, t1), slice(p0, p1))
        for i, (t0, t1) in enumerate(zip(t_edges[:-1], t_edges[1:]))
        for j, (p0, p1) in enumerate(zip(p_edges[:-1], p_edges[1:]))
    ]
    geom_name = f"observability-geometry-{token}"
    geom_layer = {(geom_name, *ij): (geometry, ts, ps) for ij, ts, ps in blocks}
    chunk_sizes = (tuple(np.diff(t_edges).tolist()), tuple(np.diff(p_edges).tolist()))
    g = {}
    for k, dt in dtypes.items():
        name = f"observability-{k}-{token}"
        layer = {(name, *ij): (operator.getitem, (geom_name, *ij), k) for ij, _, _ in blocks}
        graph = HighLevelGraph({geom_name: geom_layer, name: layer}, {geom_name: set(), name: {geom_name}})
        g[k] = da.Array(graph, name, chunks=chunk_sizes, dtype=dt)
    return g


def observability_dataset(
    campaign: Campaign, ephem: xr.Dataset, fp: Footprint, chunks: dict | None = None
) -> xr.Dataset:
    """(time, pixel) observability over the footprint from the ephemeris product.  ``chunks``
    ({"time": n, "pixel": m}): the variables are lazy (dask), each chunk's geometry computed
    when it is written, so a campaign is never held whole; None: computed here at once.  Each
    sample's geometry depends on that sample alone, so both give the same values.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (Earth radius, constraints).
    ephem : xarray.Dataset
        :func:`ephemeris_dataset`'s dataset (n_time samples).
    fp : Footprint
        The footprint (n_pixel pixels).
    chunks : dict of str to int, optional
        ``{"time": n, "pixel": m}`` chunk lengths for lazy variables; None: computed at once.

    Returns
    -------
    xarray.Dataset
        observability.zarr's dataset, each variable (time, pixel): ``observable`` (bool),
        ``violations`` (uint8 bit mask), ``sun_angle_deg``, ``moon_angle_deg``,
        ``earth_limb_angle_deg``, ``door_opening_deg`` (float32 deg); coordinates ``time``,
        ``pixel``, ``ra_deg``/``dec_deg`` (ICRS deg); HEALPix and campaign attributes.
    """
    sat_all = ephem["satellite_position_km"].values
    bodies_all = {b: ephem["body_position_km"].sel(body=b).values for b in ("sun", "moon")}
    los_all = radec_to_unit(fp.ra_deg, fp.dec_deg)

    floats = ("sun_angle_deg", "moon_angle_deg", "earth_limb_angle_deg", "door_opening_deg")  # float32, deg

    def geometry(ts: slice, ps: slice) -> dict:
        g = observing_geometry(
            sat_all[ts, None, :],
            {b: v[ts, None, :] for b, v in bodies_all.items()},
            los_all[None, ps, :],
            campaign.earth.radius_km,
            campaign.constraints,
        )
        return {
            "observable": g["observable"],
            "violations": g["violations"],
            **{k: g[k].astype(np.float32) for k in floats},
        }

    if chunks is None:
        g = geometry(slice(None), slice(None))
    else:
        import dask

        nt, npix = sat_all.shape[0], los_all.shape[0]
        # geometry()'s dtypes, declared: a skeleton (background_init) computes no sample
        dtypes = {
            "observable": np.dtype(bool),
            "violations": np.dtype(np.uint8),
            **{k: np.dtype(np.float32) for k in floats},
        }
        t_edges = list(range(0, nt, int(chunks["time"]))) + [nt]
        p_edges = list(range(0, npix, int(chunks["pixel"]))) + [npix]
        token = dask.base.tokenize(
            sat_all,
            bodies_all,
            los_all,
            campaign.earth.radius_km,
            repr(campaign.constraints),
            t_edges,
            p_edges,
        )
        g = _chunked_arrays(geometry, dtypes, (t_edges, p_edges), token)
    return _observability_from(g, ephem, fp, campaign)
