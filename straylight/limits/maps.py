"""The limits' HEALPix FITS maps: the per-pixel campaign summaries of limits.zarr (best and
median limit per band, observable fraction) as full-sky healpy-readable maps."""

from __future__ import annotations

import numpy as np

from straylight.limits.point_source import SNR

__all__ = ["write_limit_maps"]


def write_limit_maps(ds, out_dir, end=None) -> list:
    """HEALPix FITS maps (healpy-readable): limit_best_<band>, limit_median_<band>,
    observable_fraction; healpy's UNSEEN outside the footprint and where ``ds`` has NaN (never
    observable), the HEALPix convention for a missing pixel.

    Parameters
    ----------
    ds : xarray.Dataset
        A :func:`~straylight.limits.cube.limits_dataset` (eager or loaded): the summaries,
        ``pixel`` indices and the ``healpix_nside``, ``healpix_ordering`` and ``campaign``
        attributes.
    out_dir : str or path-like
        Folder for the maps (created if missing).
    end : str, astropy.time.Time or None
        The campaign's end (``campaign.end``, UTC; its samples lie before it), written as
        ``DATE-END``; None: the last time sample plus the grid's step.

    Returns
    -------
    list of pathlib.Path
        The FITS files written: ``limit_best_<band>.fits`` and ``limit_median_<band>.fits`` per
        band (mag(AB)), then ``observable_fraction.fits``; each a full-sky float32 map, ICRS.
        A band's maps carry ``EXPTIME`` (the total survey exposure, s), ``NEXP`` exposures of
        ``EXPONE`` s each, and every map ``DATE-BEG``/``DATE-END``: the campaign's start and end.
    """
    from pathlib import Path

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    common = _common_cards(ds, end)
    written = []
    for ib, b in enumerate(ds["band"].values):
        for stat in ("best", "median"):
            name = f"limit_{stat}_{b}"
            values = ds[f"limiting_mag_{stat}"].values[:, ib]
            written.append(
                _write_map(ds, out_dir / f"{name}.fits", values, "mag(AB)", common + _band_cards(ds, b))
            )
    path = out_dir / "observable_fraction.fits"
    written.append(_write_map(ds, path, ds["observable_fraction"].values, "1", list(common)))
    return written


def _common_cards(ds, end) -> list:
    """Every map's header cards: the campaign, its start and end (UTC) and its time samples."""
    times = ds["time"].values
    iso = (lambda t: str(np.datetime_as_string(t, unit="s"))) if times.dtype.kind == "M" else str
    if end is None:  # the grid's end: one step after its last sample
        end = times.max() + (times[1] - times[0] if times.size > 1 else times[0] - times[0])
    elif times.dtype.kind == "M":
        from straylight.sky.timeutil import parse_utc

        end = np.datetime64(parse_utc(end, "campaign.end").utc.datetime, "s")
    return [
        ("CAMPAIGN", str(ds.attrs["campaign"])[:68], "straylight campaign name"),
        ("DATE-BEG", iso(times.min()), "campaign start (UTC)"),
        ("DATE-END", iso(end), "campaign end (UTC)"),
        ("NTIMES", int(times.size), "campaign time samples"),
    ]


def _band_cards(ds, band) -> list:
    """A band's maps' header cards: the band, its exposures (s) and the limit's S/N."""
    b = ds.sel(band=band)
    return [
        ("BAND", str(band), "CSST band"),
        ("NEXP", int(b["n_exposures"]), "survey exposures per field"),
        ("EXPTIME", float(b["exposure_s"] * b["n_exposures"]), "[s] total survey exposure"),
        ("EXPONE", float(b["exposure_s"]), "[s] one survey exposure"),
        ("SNR", SNR, "S/N of the point-source limit (EE80)"),
    ]


def _write_map(ds, path, values, unit: str, header: list):
    """A full-sky float32 HEALPix map at ``path`` of ``values`` (``unit``) at ``ds``'s pixels,
    healpy's UNSEEN elsewhere and where NaN, with the ``header`` cards; returns ``path``."""
    from straylight.util.healpix import healpy
    from straylight.util.io import atomic_path

    hp = healpy()
    nside = int(ds.attrs["healpix_nside"])
    nest = ds.attrs["healpix_ordering"].upper() == "NESTED"
    m = np.full(hp.nside2npix(nside), hp.UNSEEN, dtype=np.float32)
    m[ds["pixel"].values] = np.where(np.isnan(values), hp.UNSEEN, values)
    with atomic_path(path) as tmp:
        hp.write_map(
            str(tmp),
            m,
            nest=nest,
            coord="C",
            column_names=[path.stem[:68].upper()],
            column_units=[unit],
            dtype=np.float32,
            overwrite=True,
            extra_header=header,
        )
    return path
