"""5-sigma point-source limiting magnitudes (issue #6).

For a band with n exposures of t seconds (total T = n t), a point source of AB magnitude m gives
S = f80 F(m) T electrons inside the 80 % encircled-energy aperture (radius r80, N_pix pixels),
with F(m) = 10^(-0.4 m) ZP pi D^2 / 4 and ZP the band's AB photon zero point.  The noise is
sigma^2 = S + N_pix (B T + D T + n RN^2), B the sky + stray-light rate (e-/s/pix), D the dark
current and RN the read noise.  The 5-sigma limit solves S = 5 sigma:
    S = (25 + sqrt(625 + 100 N_b)) / 2,   N_b = N_pix (B T + D T + n RN^2).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from straylight.optics.bandpass import load_band
from straylight.config import Campaign

if TYPE_CHECKING:
    import xarray as xr

EE_FRACTION = 0.8
SNR = 5.0


@dataclass(frozen=True)
class SurveyExposure:
    """A band's survey exposures and the detector noise terms (from the instrument config)."""

    n_exposures: int
    exposure_s: float
    read_noise_e: float
    dark_e_per_s: float
    n_pix: float  # pixels in the 80 % encircled-energy aperture
    zero_point_e_per_s: float  # AB mag 0 source, e-/s through the whole aperture

    @property
    def total_s(self) -> float:
        return self.n_exposures * self.exposure_s


def survey_exposure(campaign: Campaign, band_name: str) -> SurveyExposure:
    inst = campaign.instrument
    b = inst["bands"][band_name]
    r80 = campaign.instrument_value("detector", "ee80_radius_arcsec") / campaign.pixel_scale_arcsec
    band = load_band(inst, band_name, campaign.instrument_path.parent)
    zp_e = band.ab_zero_point_photons_s_m2 * np.pi * campaign.instrument_value("telescope", "aperture_diameter_m") ** 2 / 4
    return SurveyExposure(int(b["n_exposures"]), float(b["exposure_s"]),
                          campaign.instrument_value("detector", "read_noise_e"),
                          campaign.instrument_value("detector", "dark_current_e_per_s"), np.pi * r80**2, zp_e)


#: name of the (band) coordinate of background.zarr and limits.zarr holding each band's zero point
ZERO_POINT_NAME = "mag_zero_point"


def sky_zero_points(campaign: Campaign, bands=None) -> dict:
    """Each band's AB surface-brightness zero point, mag/arcsec2 at 1 e-/s/pixel (see
    :func:`straylight.sources.photometry.sky_zero_point_mag_per_arcsec2`): the instrument's throughput,
    aperture and pixel scale, nothing else."""
    from straylight.sources.photometry import sky_zero_point_mag_per_arcsec2

    d = campaign.instrument_value("telescope", "aperture_diameter_m")
    pix = campaign.pixel_scale_arcsec
    return {b: sky_zero_point_mag_per_arcsec2(load_band(campaign.instrument, b, campaign.instrument_path.parent), d, pix)
            for b in (bands or campaign.bands)}


def zero_point_coord(campaign: Campaign, bands) -> tuple:
    """The products' ``mag_zero_point`` (band) coordinate: mag/arcsec2 = zp - 2.5 log10(e-/s/pixel)."""
    zp = sky_zero_points(campaign, [str(b) for b in bands])
    return ("band", np.array([zp[str(b)] for b in bands], dtype=np.float64),
            {"units": "mag(AB) arcsec-2",
             "long_name": "AB surface brightness of a background of 1 e-/s/pixel; "
                          "mag_per_arcsec2 = mag_zero_point - 2.5 log10(rate / (electron / (s pixel)))"})


def point_source_limit(background_e_per_s_per_pix, band_name: str, campaign: Campaign) -> np.ndarray:
    """5-sigma AB limiting magnitude for the band's survey exposures at the given background."""
    return _limit_mag(background_e_per_s_per_pix, survey_exposure(campaign, band_name))


def _limit_mag(background_e_per_s_per_pix, x: SurveyExposure) -> np.ndarray:
    """5-sigma AB limiting magnitude for the exposures ``x`` at the background (e-/s/pix)."""
    t_tot = x.total_s
    bkg = np.asarray(background_e_per_s_per_pix, dtype=float)
    n_b = x.n_pix * (bkg * t_tot + x.dark_e_per_s * t_tot + x.n_exposures * x.read_noise_e**2)
    s = (SNR**2 + np.sqrt(SNR**4 + 4 * SNR**2 * n_b)) / 2.0
    return -2.5 * np.log10(s / (EE_FRACTION * t_tot * x.zero_point_e_per_s))


#: pixels per task of the per-pixel summaries, which need every time of a pixel at once: a
#: month at 5-minute cadence, 7 bands, float32 is 62 MB per task
SUMMARY_PIXELS_PER_TASK = 256


def limits_dataset(campaign: Campaign, background) -> "xr.Dataset":
    """(time, pixel, band) 5-sigma limits from background.zarr's ``total``, plus per-pixel
    campaign summaries over observable times (best, median) and the observable fraction.
    Pixels never observable get NaN in the summaries (the HEALPix FITS maps turn it into
    healpy's UNSEEN: :func:`write_limit_maps`).  A float sentinel here would pass as a
    magnitude: a plot's colour range or a mean over pixels would take -1.6e30 mag.

    ``background`` may be lazy (``xr.open_zarr``): the result is then lazy too, and writing it
    streams over the cube's chunks (the limits chunk by chunk, the summaries
    SUMMARY_PIXELS_PER_TASK pixels at a time over all times) instead of holding the campaign."""
    import xarray as xr

    bands = [str(b) for b in background["band"].values]
    exposures = [survey_exposure(campaign, b) for b in bands]

    def limits(total):  # (..., band) e-/s/pix -> mag(AB), float32
        out = np.empty(total.shape, np.float32)
        for ib, x in enumerate(exposures):
            out[..., ib] = _limit_mag(total[..., ib], x)
        return out

    def best_and_median(lim, observable):  # (pixel, band, time), (pixel, 1, time) -> (pixel, band, 2)
        import warnings

        masked = np.where(observable, lim, np.nan)
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            best = np.nanmax(masked, axis=-1)
            median = np.nanmedian(masked, axis=-1)
        seen = observable.any(axis=-1)
        return np.stack([np.where(seen, best, np.nan), np.where(seen, median, np.nan)], axis=-1).astype(np.float32)

    lim = xr.apply_ufunc(limits, background["total"], dask="parallelized", output_dtypes=[np.float32])
    observable = background["observable"]
    whole_times = {"time": -1, "pixel": SUMMARY_PIXELS_PER_TASK}
    lim_t, obs_t = (lim, observable) if lim.chunks is None else (lim.chunk(whole_times), observable.chunk(whole_times))
    summary = xr.apply_ufunc(best_and_median, lim_t, obs_t, input_core_dims=[["time"], ["time"]],
                             output_core_dims=[["stat"]], dask="parallelized", output_dtypes=[np.float32],
                             dask_gufunc_kwargs={"output_sizes": {"stat": 2}})
    frac = observable.mean("time").astype(np.float32)
    desc = ", ".join(f"{b}: {campaign.instrument['bands'][b]['n_exposures']} x "
                     f"{campaign.instrument['bands'][b]['exposure_s']} s" for b in bands)
    ds = xr.Dataset(
        {
            "limiting_mag": (("time", "pixel", "band"), lim.data,
                             {"units": "mag(AB)", "long_name": f"5-sigma point-source limit in the EE80 aperture ({desc})"}),
            "limiting_mag_best": (("pixel", "band"), summary.isel(stat=0).transpose("pixel", "band").data,
                                  {"units": "mag(AB)",
                                   "long_name": "deepest limit over observable times (NaN: never observable)"}),
            "limiting_mag_median": (("pixel", "band"), summary.isel(stat=1).transpose("pixel", "band").data,
                                    {"units": "mag(AB)",
                                     "long_name": "median limit over observable times (NaN: never observable)"}),
            "observable_fraction": (("pixel",), frac.data, {"units": "1", "long_name": "fraction of campaign times observable"}),
            "observable": (("time", "pixel"), observable.data,
                           {"units": "1", "long_name": "pointing satisfies every constraint"}),
        },
        coords={**{k: background[k] for k in ("time", "pixel", "ra_deg", "dec_deg", "band")},
                ZERO_POINT_NAME: zero_point_coord(campaign, background["band"].values),
                "n_exposures": ("band", np.array([campaign.instrument["bands"][str(b)]["n_exposures"]
                                                  for b in background["band"].values], np.int32),
                                {"units": "1", "long_name": "survey exposures per field"}),
                "exposure_s": ("band", np.array([campaign.instrument["bands"][str(b)]["exposure_s"]
                                                 for b in background["band"].values], np.float64),
                               {"units": "s", "long_name": "duration of one survey exposure"})},
        attrs={k: background.attrs[k] for k in ("healpix_nside", "healpix_ordering", "healpix_frame", "campaign")},
    )
    return ds


def write_limit_maps(ds, out_dir) -> list:
    """HEALPix FITS maps (healpy-readable): limit_best_<band>, limit_median_<band>,
    observable_fraction; healpy's UNSEEN outside the footprint and where ``ds`` has NaN (never
    observable), the HEALPix convention for a missing pixel."""
    from pathlib import Path

    import healpy as hp

    from straylight.util.io import atomic_path

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    nside = int(ds.attrs["healpix_nside"])
    nest = ds.attrs["healpix_ordering"].upper() == "NESTED"
    pix = ds["pixel"].values
    written = []

    times = ds["time"].values
    iso = (lambda t: str(np.datetime_as_string(t, unit="s"))) if times.dtype.kind == "M" else str
    common = [("CAMPAIGN", str(ds.attrs["campaign"])[:68], "straylight campaign name"),
              ("DATE-BEG", iso(times.min()), "first campaign time (UTC)"),
              ("DATE-END", iso(times.max()), "last campaign time (UTC)"),
              ("NTIMES", int(times.size), "campaign time samples")]

    def write(name, values, unit, band=None):
        m = np.full(hp.nside2npix(nside), hp.UNSEEN, dtype=np.float32)
        m[pix] = np.where(np.isnan(values), hp.UNSEEN, values)
        header = list(common)
        if band is not None:
            b = ds.sel(band=band)
            header += [("BAND", str(band), "CSST band"),
                       ("NEXP", int(b["n_exposures"]), "survey exposures per field"),
                       ("EXPTIME", float(b["exposure_s"]), "[s] one survey exposure"),
                       ("TEXPTIME", float(b["exposure_s"] * b["n_exposures"]), "[s] total survey exposure"),
                       ("SNR", SNR, "S/N of the point-source limit (EE80)")]
        path = out_dir / f"{name}.fits"
        with atomic_path(path) as tmp:
            hp.write_map(str(tmp), m, nest=nest, coord="C", column_names=[name[:68].upper()],
                         column_units=[unit], dtype=np.float32, overwrite=True, extra_header=header)
        written.append(path)

    for ib, b in enumerate(ds["band"].values):
        write(f"limit_best_{b}", ds["limiting_mag_best"].values[:, ib], "mag(AB)", b)
        write(f"limit_median_{b}", ds["limiting_mag_median"].values[:, ib], "mag(AB)", b)
    write("observable_fraction", ds["observable_fraction"].values, "1")
    return written
