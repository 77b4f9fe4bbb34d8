"""The stores the cube's workers write: background.zarr, and beside it observability.zarr and
limits.zarr.

Layout of ``background.zarr`` (xarray Dataset; its variables and chunks:
:mod:`straylight.cube.layout`):

* dims (time, pixel, band); one float32 variable per component (e- s-1 pixel-1) plus ``total``;
  ``observable`` (bool) and ``violations`` (uint8 bit mask) and ``door_opening_deg`` on
  (time, pixel); coords time (UTC), pixel (HEALPix index), ra_deg/dec_deg, band, and
  ``mag_zero_point`` (band): AB mag/arcsec2 = mag_zero_point - 2.5 log10(e-/s/pixel);
  ``faint_star_map`` (pixel, band), computed once when the store is laid down;
* attrs: HEALPix nside, ordering and frame, campaign, models, provenance pointers.

The skeletons (metadata and coordinates, no data chunks) are laid down first (:func:`init_store`,
:func:`init_observability_store`, :func:`init_limits_store`).  Each region is then written to its
own part of each store exactly once, through the stores' arrays opened once per worker
(:func:`open_stores`, :meth:`StoreArrays.write_region`).  A region's geometry (observable,
violations, the Sun, Moon and limb angles, the door) is observability.zarr's, so the worker
writes that region of the observability store too, instead of a later step computing the
geometry again, and the region's 5-sigma limits, from the total it has just computed
(:func:`region_limits`), to the limits store, instead of a later step reading the total back.
Once every time block is done, :func:`publish_work_store` makes the observability and limits
stores the products.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from straylight.cube import layout as cube_layout
from straylight.cube.layout import (
    CUBE_PIXEL_VARIABLES,
    LIMITS_REGION_VARIABLES,
    OBSERVABILITY_VARIABLES,
    CubeStores,
    cube_chunks,
    is_envelope_end_part,
)
from straylight.errors import OutputError
from straylight.limits.point_source import ZERO_POINT_NAME, zero_point_coord
from straylight.sky.geometry import violation_mask_attrs
from straylight.storage.bitround import stored_values

if TYPE_CHECKING:  # xarray where a Dataset is made: a worker writing regions does without it
    import xarray as xr

    from straylight.config import Campaign
    from straylight.cube.footprint import Footprint

__all__ = [
    "StoreArrays",
    "empty_cube",
    "init_limits_store",
    "init_observability_store",
    "init_store",
    "open_stores",
    "publish_work_store",
    "region_limits",
    "region_write_error",
    "store_arrays",
    "stored_faint_map",
]


def empty_cube(campaign: Campaign, fp: Footprint, times, model, stars_path=None, stars=None) -> xr.Dataset:
    """The cube's skeleton backed by lazy dask zeros (for writing metadata only); ``model``: the
    campaign's BackgroundModel, whose models record it carries (building the earthshine table if
    one runs and is not cached); ``stars``: the off-field stars of the catalog at ``stars_path``
    (:func:`~straylight.cube.region.offfield_stars`).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (bands, chunking, config).
    fp : Footprint
        The survey footprint (n_pixel pixels).
    times : astropy.time.Time, shape (n_time,)
        The cube's UTC sample times.
    model : BackgroundModel
        The campaign's model (its models record goes into the ``models`` attribute).
    stars_path : str or path-like, optional
        The star catalog; None: no stars (``stars_catalog`` is ``"none"``).
    stars : straylight.sources.stars_table.StarTable, optional
        The catalog's off-field stars (required when ``stars_path`` is given).

    Returns
    -------
    xarray.Dataset
        Lazy dask zeros, chunked as the cube: each component and ``total`` (time, pixel, band)
        float32 e-/s/pix; ``observable`` bool, ``violations`` uint8, ``door_opening_deg``
        float32 deg on (time, pixel); coordinates ``time`` (UTC datetime64), ``pixel``,
        ``ra_deg``/``dec_deg`` (ICRS deg), ``band``, ``mag_zero_point`` (AB mag/arcsec2); the
        HEALPix, campaign, stars and models attributes.
    """
    import dask.array as da
    import xarray as xr

    from straylight.model import registry

    nt, npix, nb = len(times), fp.pixels.size, len(campaign.bands)
    ch = cube_chunks(campaign, nt, npix)
    chunks3 = (ch["time"], ch["pixel"], ch["band"])
    chunks2 = (ch["time"], ch["pixel"])
    data = {}
    long_names = registry.long_names()
    for comp in registry.component_names(total=True) + cube_layout.CUBE_PART_VARIABLES:
        part = comp in cube_layout.CUBE_PART_VARIABLES  # kept where observable only
        data[comp] = xr.Variable(
            ("time", "pixel", "band"),
            da.zeros((nt, npix, nb), chunks=chunks3, dtype=np.float32),
            {
                "units": "electron / (s pixel)",
                "long_name": long_names[comp]
                + (", part of earthshine (NaN: not observable)" if part else ""),
            },
        )
    data["observable"] = xr.Variable(
        ("time", "pixel"),
        da.zeros((nt, npix), chunks=chunks2, dtype=bool),
        {"units": "1", "long_name": "pointing satisfies every constraint"},
    )
    data["violations"] = xr.Variable(
        ("time", "pixel"), da.zeros((nt, npix), chunks=chunks2, dtype=np.uint8), violation_mask_attrs()
    )
    data["door_opening_deg"] = xr.Variable(
        ("time", "pixel"),
        da.zeros((nt, npix), chunks=chunks2, dtype=np.float32),
        {"units": "deg", "long_name": "aperture door opening (0 = no allowed state)"},
    )
    ds = xr.Dataset(
        data,
        coords={
            "time": ("time", times.datetime64, {"long_name": "UTC sample time"}),
            "pixel": ("pixel", fp.pixels, {"long_name": "HEALPix pixel index"}),
            "ra_deg": ("pixel", fp.ra_deg, {"units": "deg", "long_name": "ICRS RA of pixel centre"}),
            "dec_deg": ("pixel", fp.dec_deg, {"units": "deg", "long_name": "ICRS Dec of pixel centre"}),
            "band": ("band", np.array(campaign.bands, dtype=object), {"long_name": "CSST band"}),
            ZERO_POINT_NAME: zero_point_coord(campaign, campaign.bands),
        },
        attrs=_cube_attrs(campaign, fp, model, stars_path, stars),
    )
    return ds


def _cube_attrs(campaign: Campaign, fp: Footprint, model, stars_path, stars) -> dict:
    """The cube's attributes: its HEALPix grid, the campaign's model settings, the stars, the
    models record, the Earth's albedo and the envelope (arguments as :func:`empty_cube`'s)."""
    from straylight.model.envelope import campaign_envelope

    return {
        "campaign": campaign.name,
        "healpix_nside": fp.nside,
        "healpix_ordering": fp.ordering.upper(),
        "healpix_frame": "ICRS",
        "zodiacal_spectrum": campaign.settings.models.zodiacal_spectrum,
        "zodiacal_reddening_per_dex": list(campaign.settings.models.zodiacal_reddening.as_tuple()),
        "moon_phase_law": campaign.settings.models.moon_phase_law,
        # the instrument file's own words, as written ("" where it has no pst section): a
        # record of the file, like the provenance's copy of it, not a setting read
        "pst_source": str(campaign.instrument_mapping().get("pst", {}).get("source", "")),
        "stars_included": int(len(stars.ra_deg)) if stars_path else 0,
        "stars_in_faint_map": int(len(stars.faint_ra_deg)) if stars_path else 0,
        "stars_catalog": Path(stars_path).name if stars_path else "none",
        "stars_offfield_mag_limit": float(campaign.settings.stars.offfield_mag_limit),
        "stars_faint_map": int(campaign.settings.stars.faint_map),
        "chunking": "time block x pixel block x all bands",
        # which models ran and their error budget (the earthshine table is built here, once,
        # before the time-block jobs start)
        "models": json.dumps(model.models_record(), sort_keys=True),
        # the Earth's band albedos, and the assumption envelope: each parameter's range, the
        # parts it scales and its factors per band (limits.zarr's pessimistic and optimistic
        # depths)
        "earth_albedo": json.dumps(_earth_albedo_record(campaign, model), sort_keys=True),
        "envelope": json.dumps(campaign_envelope(campaign, context=model.context).attrs(), sort_keys=True),
    }


def _earth_albedo_record(campaign: Campaign, model) -> dict:
    """The Earth's albedo spectrum and its band albedos (JSON-able)."""
    from straylight.sources.earthshine.albedo import band_albedo

    es = campaign.settings.models.earthshine
    bands = [model.context.band(b) for b in campaign.bands]
    return {
        "spectrum": es.albedo_spectrum,
        "bond_albedo": float(es.albedo),
        "band_albedo": {
            b: band_albedo(band, es.albedo_spectrum, float(es.albedo))
            for b, band in zip(campaign.bands, bands)
        },
    }


def init_store(
    campaign: Campaign, fp: Footprint, store, stars_path=None, build_workers: int = 1, limits_store=None
) -> None:
    """Write the skeleton (metadata and coordinates, no data chunks) to ``store``, and the
    faint-star map (computed here once for the whole campaign, on ``build_workers``
    processes); an earthshine table the campaign needs (the envelope members' included) is built
    here too, before the time blocks start (``build_workers`` threads).  ``limits_store``: where
    the limits' skeleton goes too (:func:`init_limits_store`; None: not laid down).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    fp : Footprint
        The survey footprint.
    store : str or path-like
        background.zarr's path.
    stars_path : str or path-like, optional
        The star catalog; None: no stars and no faint map.
    build_workers : int, optional
        Processes for the faint map and threads for an earthshine table.
    limits_store : str or path-like, optional
        limits.zarr's work store; None: not laid down.
    """
    from straylight.cube.region import _end_models, faint_star_map, offfield_stars
    from straylight.model import BackgroundModel
    from straylight.storage.zarr_io import write_skeleton

    model = BackgroundModel(campaign, build_workers=build_workers)
    # the envelope members' tables too, here once on every core, not by each time block's worker
    for end_model in _end_models(model, campaign).values():
        end_model.models_record()
    stars = offfield_stars(campaign, stars_path)

    def skeleton():
        return empty_cube(campaign, fp, campaign.times, model, stars_path, stars)

    # the faint map's other processes start first and sum while this one lays down the skeleton
    faint, ds = faint_star_map(
        campaign, fp, stars_path, build_workers, before=skeleton, model=model, stars=stars
    )
    if limits_store is not None:
        init_limits_store(campaign, ds, limits_store)
    if faint is not None:
        ds["faint_star_map"] = faint
    # the products' codecs (bit-rounded floats); the faint map exactly, the time blocks read it
    write_skeleton(ds, store, campaign.settings.storage, lossless=("faint_star_map",))


def init_observability_store(campaign: Campaign, fp: Footprint, ephem: xr.Dataset, store) -> None:
    """Lay down observability.zarr's skeleton at ``store`` (metadata, coordinates, the products'
    codecs; no data chunks), chunked as the cube: the cube's workers write each region's
    observability beside its background (:meth:`StoreArrays.write_region`), and
    :func:`publish_work_store` makes it the product once every time block is done.  The
    variables and attributes are those of
    :func:`straylight.cube.products.observability_dataset` (``ephem``: the ephemeris product),
    whose geometry the cube's is, sample by sample, bit for bit.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    fp : Footprint
        The survey footprint.
    ephem : xarray.Dataset
        The ephemeris product (its ``time`` dimension sets the store's times).
    store : str or path-like
        The observability work store's path.
    """
    from straylight.cube.products import observability_dataset
    from straylight.storage.zarr_io import write_skeleton

    chunks = cube_chunks(campaign, ephem.sizes["time"], fp.pixels.size)
    write_skeleton(
        observability_dataset(campaign, ephem, fp, chunks=chunks), store, campaign.settings.storage
    )


def init_limits_store(campaign: Campaign, cube, store) -> None:
    """Lay down limits.zarr's skeleton at ``store`` (metadata, coordinates, the products' codecs;
    no data chunks) from the cube's skeleton ``cube`` (:func:`empty_cube`): the variables,
    attributes and chunks of :func:`straylight.limits.cube.limits_dataset` on the cube.  The
    cube's workers write each region's ``limiting_mag`` and ``observable``
    (:meth:`StoreArrays.write_region`); the limits rule adds the per-pixel summaries in
    :func:`publish_work_store`.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    cube : xarray.Dataset
        The cube's skeleton (:func:`empty_cube`).
    store : str or path-like
        The limits work store's path.
    """
    from straylight.limits.cube import limits_dataset
    from straylight.storage.zarr_io import write_skeleton

    write_skeleton(limits_dataset(campaign, cube, per_sample_envelope=True), store, campaign.settings.storage)


def stored_faint_map(store) -> np.ndarray | None:
    """The store's faint_star_map, (pixel, band) e-/s/pix, or None when it has none.

    Parameters
    ----------
    store : str or path-like
        background.zarr's path.

    Returns
    -------
    ndarray, shape (n_pixel, n_band), or None
        The faint stars' map over the whole footprint, e-/s/pix.
    """
    import zarr

    group = zarr.open_group(str(store), mode="r", use_consolidated=False)
    return group["faint_star_map"][...] if "faint_star_map" in group else None


def region_limits(campaign: Campaign, region) -> dict:
    """A computed region's limits.zarr variables (name -> (time, pixel[, band]) array): the
    5-sigma limits of its computed ``total`` (:func:`straylight.limits.point_source.band_limits`),
    and its ``observable``; ``region``:
    :func:`~straylight.cube.region.compute_region`'s Dataset or
    :func:`~straylight.cube.region.region_values`' arrays.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (its bands' survey exposures).
    region : xarray.Dataset or dict
        ``total`` (n_time, n_pixel, n_band) in e-/s/pix and ``observable`` (n_time, n_pixel).

    Returns
    -------
    dict of str to ndarray
        ``limiting_mag``: float32, shape (n_time, n_pixel, n_band), 5-sigma AB mag;
        ``observable``: bool, shape (n_time, n_pixel); ``limiting_mag_pessimistic`` and
        ``limiting_mag_optimistic``: the limits at the assumption envelope's ends
        (:func:`~straylight.limits.envelope.envelope_limits`), float32 (n_time, n_pixel, n_band),
        NaN where not observable; ``limiting_mag_p16`` and ``limiting_mag_p84``: the depth
        budget's (:func:`~straylight.limits.budget.budget_limits`), where it has inputs.
    """
    from straylight.limits.budget import budget_limits, depth_budget
    from straylight.limits.envelope import envelope_limits
    from straylight.limits.point_source import band_limits, campaign_exposures
    from straylight.model.envelope import campaign_envelope

    exposures = campaign_exposures(campaign)
    terms = depth_budget(campaign)
    return {
        "limiting_mag": band_limits(np.asarray(region["total"]), exposures),
        "observable": np.asarray(region["observable"]),
        **envelope_limits(campaign_envelope(campaign), region, exposures),
        **(budget_limits(terms, region, exposures) if terms else {}),
    }


def store_arrays(store, names=None) -> dict:
    """The data variables ``names`` of ``store`` (None: the cube's) opened for writing whole
    chunks (name -> :class:`~straylight.storage.zarr_io.ChunkWriter`): a worker opens them once
    and writes every region through them, where xarray's region write would open the store and
    read its metadata again for each region.  The same codecs encode the same values, so the
    chunks' bytes are those xarray writes.

    Parameters
    ----------
    store : str or path-like
        A Zarr store laid down by one of the ``init_*`` functions.
    names : sequence of str, optional
        Data variables to open; None: the cube's (components, total and (time, pixel) ones).

    Returns
    -------
    dict of str to ChunkWriter
        Variable name to its writer.
    """
    import zarr

    from straylight.model import registry
    from straylight.storage.zarr_io import ChunkWriter

    group = zarr.open_group(str(store), mode="r+", use_consolidated=False)
    names = (
        names or registry.component_names(total=True) + cube_layout.CUBE_PART_VARIABLES + CUBE_PIXEL_VARIABLES
    )
    return {name: ChunkWriter(group[name]) for name in names}


@dataclass
class StoreArrays:
    """The arrays of a :class:`CubeStores` opened for writing whole chunks (:func:`store_arrays`),
    in the thread that opened them: the cube's, and the observability and limits stores' (None
    where the store is not written)."""

    stores: CubeStores
    cube: dict
    observability: dict | None = None
    limits: dict | None = None

    def write_region(
        self,
        t_slice: slice,
        p_slice: slice,
        region: dict,
        angles: dict | None = None,
        limits: dict | None = None,
    ) -> None:
        """Write a computed region: ``region`` (name -> array) to the cube's store, its
        observability (``region``'s flags and ``angles``) to the observability store, ``limits``
        (:func:`region_limits`) to the limits store; each rounded as its array's attributes
        record (:func:`~straylight.storage.bitround.stored_values`).  OutputError when the file
        system refuses (no space, no access): the time block's sentinel is then not written.

        Parameters
        ----------
        t_slice, p_slice : slice
            The region: time indices and footprint pixel indices (one chunk).
        region : dict of str to ndarray
            :func:`~straylight.cube.region.region_values`' arrays, (n_time, n_pixel[, n_band]).
        angles : dict of str to ndarray, optional
            The observability angles, (n_time, n_pixel) float32 deg; required when the
            observability store is written.
        limits : dict of str to ndarray, optional
            :func:`region_limits`; required when the limits store is written.

        Raises
        ------
        OutputError
            When the file system refuses the write (names the store and the region).
        """
        try:
            for name, values in region.items():
                if is_envelope_end_part(name):  # for the region's limits only, not stored
                    continue
                self.cube[name][t_slice, p_slice] = stored_values(values, self.cube[name].attrs)
            if self.observability is not None:
                for name in OBSERVABILITY_VARIABLES:
                    values = angles[name] if name in angles else region[name]
                    self.observability[name][t_slice, p_slice] = stored_values(
                        values, self.observability[name].attrs
                    )
            if self.limits is not None:
                for name, values in limits.items():
                    self.limits[name][t_slice, p_slice] = stored_values(values, self.limits[name].attrs)
        except OSError as exc:  # ENOSPC, EDQUOT, EACCES...
            raise region_write_error(self.stores, t_slice, p_slice, exc) from exc


def open_stores(stores: CubeStores) -> StoreArrays:
    """``stores``' arrays opened for writing regions, in this thread.

    Parameters
    ----------
    stores : CubeStores
        The stores' paths (their skeletons laid down).

    Returns
    -------
    StoreArrays
        The cube's writers, and the observability and limits stores' (None where not written).
    """
    obs, lim = stores.observability, stores.limits
    return StoreArrays(
        stores,
        store_arrays(stores.cube),
        None if obs is None else store_arrays(obs, OBSERVABILITY_VARIABLES),
        None if lim is None else store_arrays(lim, _present(lim, LIMITS_REGION_VARIABLES)),
    )


def _present(store, names) -> tuple:
    """Those of ``names`` the store at ``store`` holds (the budget's limits need its inputs)."""
    import zarr

    group = zarr.open_group(str(store), mode="r", use_consolidated=False)
    return tuple(n for n in names if n in group)


def region_write_error(stores: CubeStores, t_slice: slice, p_slice: slice, exc: OSError) -> OutputError:
    """The error of a region's failed write: the store, the region, the cause and what to do.

    Parameters
    ----------
    stores : CubeStores
        The stores being written.
    t_slice, p_slice : slice
        The region that failed.
    exc : OSError
        The cause.

    Returns
    -------
    OutputError
        The error to raise (not raised here).
    """
    return OutputError(
        f"{stores.cube}: writing times {t_slice.start}:{t_slice.stop} x pixels "
        f"{p_slice.start}:{p_slice.stop} failed ({exc.strerror or exc}); finished time blocks "
        "are kept, free space and re-run to redo this block"
    )


def publish_work_store(work_store, product, summaries: dict | None = None, drop=()) -> None:
    """A store the cube's workers filled (``work_store``: the observability or the limits one),
    its metadata consolidated, appears at ``product`` complete or not at all: its files
    hard-linked (copied where links fail), and ``summaries`` (name -> the whole array of a
    variable the work store lays down but has no chunk of: the limits' per-pixel summaries)
    written there only.  The work store stays as it was, for a re-run of the publishing step;
    its writers (:class:`~straylight.storage.zarr_io.ChunkWriter`, zarr) replace a chunk file by
    renaming a new one into place, so a later write to the work store leaves the product's files
    as they are.

    Parameters
    ----------
    work_store : str or path-like
        The filled work store.
    product : str or path-like
        The product's path (replaced atomically).
    summaries : dict of str to array_like, optional
        Variable name to the whole array, written into the product only (the limits'
        per-pixel summaries: :func:`~straylight.limits.cube.store_limit_summaries`); None: none.
    drop : sequence of str, optional
        Variables of the work store left out of the product (the envelope's per-sample limits,
        which only its per-pixel medians need).
    """
    import os
    import shutil

    import zarr

    from straylight.storage.zarr_io import PARTIAL_SUFFIX
    from straylight.util.io import atomic_path

    zarr.consolidate_metadata(str(work_store))

    def link(src, dst):
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)

    with atomic_path(product) as tmp:
        # every time block is done, so no chunk is being written: a *.partial file is a killed
        # writer's, never part of the store
        partial = shutil.ignore_patterns(f"*{PARTIAL_SUFFIX}")
        top = os.path.abspath(str(work_store))

        def ignore(folder, names):
            dropped = set(drop) if os.path.abspath(folder) == top else set()
            return set(partial(folder, names)) | (dropped & set(names))

        shutil.copytree(work_store, tmp, copy_function=link, ignore=ignore)
        if drop:
            # the group's metadata listed the dropped variables: its own copy (not a link to the
            # work store's), consolidated again over what the product holds
            meta = Path(tmp) / "zarr.json"
            meta.unlink()
            shutil.copy2(Path(work_store) / "zarr.json", meta)
            zarr.consolidate_metadata(str(tmp))
        if summaries:
            group = zarr.open_group(str(tmp), mode="r+", use_consolidated=False)
            for name, values in summaries.items():
                # rounded as the variable's attributes record (the codecs are lossless); new chunk
                # files only: no linked file is written
                group[name][...] = stored_values(np.array(values), group[name].attrs)
