"""Figures of a campaign's products for the report (issue #8 item 1): all-sky Mollweide maps of
every component and the total per band at chosen times, time series of chosen pointings over
the first orbit and the whole campaign, and the limiting-magnitude maps.

Maps are in the cube's HEALPix frame (ICRS); pixels outside the footprint are grey.  Values are
shown as AB mag/arcsec2 (brighter = smaller), the unit planners compare with sky tables.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

ORBIT_MINUTES = 92.6  # ~400 km circular orbit: the first-orbit panel spans this long


def _mag(ds, e_per_s, band: str, campaign):
    from .bandpass import load_band
    from .offfield import magnitude_per_arcsec2

    b = load_band(campaign.instrument, band, campaign.instrument_path.parent)
    return magnitude_per_arcsec2(e_per_s, b, campaign.instrument_value("telescope", "aperture_diameter_m"),
                                 campaign.pixel_scale_arcsec)


def _full_sky(ds, values):
    import healpy as hp

    m = np.full(hp.nside2npix(int(ds.attrs["healpix_nside"])), hp.UNSEEN)
    v = np.asarray(values, float)
    m[np.asarray(ds["pixel"])] = np.where(np.isfinite(v), v, hp.UNSEEN)
    return m


def _mollview_with_unit(fig, values, unit: str, **kw) -> None:
    """healpy's mollview with a colour bar whose unit sits below the tick labels: healpy puts
    it at a fixed fraction of the bar's height, over the labels on a 2 x 4 page."""
    import healpy as hp

    hp.mollview(values, fig=fig.number, unit="", cbar=True, **kw)
    fig.axes[-1].set_xlabel(unit, fontsize=9, labelpad=2)  # the colour bar: the last axes mollview adds


def _save(fig, path: Path) -> Path:
    from .io import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png", bbox_inches="tight")  # healpy's colour-bar labels overhang the axes
    return path


def sky_maps(ds, campaign, out_dir, n_times: int = 2, bands=None, times=()) -> list:
    """Per chosen time (``times``, UTC ISO, nearest sample; else ``n_times`` evenly spread) and
    band: a 2 x 4 page of Mollweide maps, one per component, the total and the observability."""
    import healpy as hp
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .cube import CUBE_BAND_VARIABLES

    nest = str(ds.attrs["healpix_ordering"]).upper() == "NESTED"
    if times:
        from .timeutil import parse_utc

        wanted = np.asarray(parse_utc(list(times), "report.times").datetime64, dtype="datetime64[ns]")
        t_all = ds["time"].values
        idx = np.unique([int(np.argmin(np.abs(t_all - w))) for w in wanted])
    else:
        idx = np.unique(np.linspace(0, ds.sizes["time"] - 1, n_times).round().astype(int))
    written = []
    for it in idx:
        t = str(ds["time"].values[it])[:16]
        for ib, band in enumerate(ds["band"].values):
            if bands is not None and str(band) not in bands:
                continue
            fig = plt.figure(figsize=(16, 6.5))
            for k, comp in enumerate(CUBE_BAND_VARIABLES):
                e = np.asarray(ds[comp].isel(time=it, band=ib), float)
                mag = _mag(ds, e, str(band), campaign)
                finite = np.isfinite(mag)
                lo, hi = (np.percentile(mag[finite], [2, 98]) if finite.any() else (20.0, 30.0))
                _mollview_with_unit(fig, _full_sky(ds, mag), "AB mag/arcsec2", nest=nest, sub=(2, 4, k + 1),
                                    title=f"{comp}", min=lo, max=max(hi, lo + 0.1), cmap="viridis_r", notext=True)
            obs = np.asarray(ds["observable"].isel(time=it), float)
            hp.mollview(_full_sky(ds, obs), nest=nest, fig=fig.number, sub=(2, 4, 8), title="observable",
                        min=0, max=1, cmap="RdYlGn", cbar=False, notext=True)
            # models.unobservable_samples: skip leaves NaN where not observable (e: the total here)
            # a component's 0 (blocked, or skipped below its share of the tolerance) has no magnitude
            grey = "outside the footprint, a component's 0" + (", not evaluated (not observable)"
                                                               if np.isnan(e).any() else "")
            fig.suptitle(f"{campaign.name}: band {band} at {t} UTC (ICRS Mollweide; grey: {grey})")
            written.append(_save(fig, Path(out_dir) / f"sky_{band}_{t.replace(':', '').replace('-', '')}.png"))
            plt.close(fig)
    return written


def time_series(ds, campaign, out_dir, n_pointings: int = 3, pointings=()) -> list:
    """For chosen pointings (``pointings``: [ra, dec] deg, nearest footprint pixel; else
    ``n_pointings`` evenly spread pixels): total and components in each band against time, over
    the first orbit and over the whole campaign; unobservable times shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .cube import CUBE_BAND_VARIABLES

    if pointings:
        from .geometry import radec_to_unit

        centres = radec_to_unit(np.asarray(ds["ra_deg"]), np.asarray(ds["dec_deg"]))
        wanted = np.atleast_2d(radec_to_unit(*np.asarray(pointings, float).T, "report.pointings"))
        pix_idx = np.unique(np.argmax(wanted @ centres.T, axis=1))
    else:
        pix_idx = np.unique(np.linspace(0, ds.sizes["pixel"] - 1, n_pointings).round().astype(int))
    t = ds["time"].values
    minutes = (t - t[0]) / np.timedelta64(1, "m")
    written = []
    for ip in pix_idx:
        ra, dec = float(ds["ra_deg"][ip]), float(ds["dec_deg"][ip])
        sub = ds.isel(pixel=ip)
        obs = np.asarray(sub["observable"], bool)
        for span, sel in (("orbit", minutes <= ORBIT_MINUTES), ("campaign", np.ones(minutes.size, bool))):
            bands = list(ds["band"].values)
            fig, axes = plt.subplots(len(bands), 1, figsize=(10, 2.0 * len(bands)), sharex=True)
            for ax, band in zip(np.atleast_1d(axes), bands):
                ib = bands.index(band)
                for comp in CUBE_BAND_VARIABLES:
                    y = np.asarray(sub[comp].isel(band=ib), float)[sel]
                    ax.semilogy(minutes[sel], np.maximum(y, 1e-12), lw=1.6 if comp == "total" else 0.9,
                                color="k" if comp == "total" else None, label=comp)
                for a, b in _runs(~obs[sel]):
                    ax.axvspan(minutes[sel][a], minutes[sel][b], color="0.85", lw=0)
                ax.set_ylabel(f"{band}\ne-/s/pix")
                ax.set_ylim(1e-6, None)
            np.atleast_1d(axes)[0].legend(fontsize=7, ncol=7, loc="upper right")
            np.atleast_1d(axes)[-1].set_xlabel(f"minutes after {str(t[0])[:16]} UTC (grey: not observable)")
            fig.suptitle(f"{campaign.name}: pointing RA {ra:.1f}, Dec {dec:.1f} deg, {span}")
            fig.tight_layout()
            written.append(_save(fig, Path(out_dir) / f"series_{span}_ra{ra:06.2f}_dec{dec:+06.2f}.png"))
            plt.close(fig)
    return written


def _runs(mask):
    """(start, end) index pairs of the True runs of a boolean array."""
    idx = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(a, max(b - 1, a)) for a, b in zip(idx[::2], idx[1::2])]


def limit_maps(limits_ds, campaign, out_dir) -> list:
    """Best and median 5-sigma limiting magnitude over the campaign, per band (Mollweide)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nest = str(limits_ds.attrs.get("healpix_ordering", "RING")).upper() == "NESTED"
    written = []
    for stat in ("best", "median"):
        var = f"limiting_mag_{stat}"
        if var not in limits_ds:
            continue
        fig = plt.figure(figsize=(16, 6.5))
        for ib, band in enumerate(limits_ds["band"].values):
            v = np.asarray(limits_ds[var].isel(band=ib), float)
            finite = np.isfinite(v)
            lo, hi = (np.percentile(v[finite], [2, 98]) if finite.any() else (20.0, 28.0))
            _mollview_with_unit(fig, _full_sky(limits_ds, v), "AB mag (5 sigma)", nest=nest, sub=(2, 4, ib + 1),
                                title=str(band), min=lo, max=max(hi, lo + 0.1), cmap="magma", notext=True)
        fig.suptitle(f"{campaign.name}: {stat} 5-sigma point-source limit over the campaign (survey exposures; "
                     "grey: outside the footprint or never observable)")
        written.append(_save(fig, Path(out_dir) / f"limits_{stat}.png"))
        plt.close(fig)
    return written


def campaign_figures(background_path, limits_path, campaign, out_dir) -> list:
    import xarray as xr

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ds = xr.open_zarr(background_path)
    rc = campaign.config["report"]
    unknown = sorted(set(rc.get("sky_map_bands") or ()) - {str(b) for b in ds["band"].values})
    if unknown:
        from .errors import ConfigError

        raise ConfigError(f"{campaign.path}: report.sky_map_bands: {', '.join(unknown)} not among the cube's bands "
                          f"{', '.join(str(b) for b in ds['band'].values)}")
    written = (sky_maps(ds, campaign, out, int(rc["sky_map_times"]), rc.get("sky_map_bands"), rc.get("times") or ())
               + time_series(ds, campaign, out, int(rc["series_pointings"]), rc.get("pointings") or ()))
    return written + limit_maps(xr.open_zarr(limits_path), campaign, out)
