"""Reproductions of the paper's scenarios.

:func:`earthshine_scenario` - sect. 3.3: at 2026-01-01 00:50 UTC, pointings on a grid RA 0-345 deg
(15 deg steps) x Dec -75 to +75 deg (15 deg steps); CSST earthshine (direct + door) per band
against the bright-limb angle (the avoidance constraint's: to the nearest sunlit point of the
disc at the top of the atmosphere), for pointings in the sunlit region (nearest limb bright).

The HST comparison (:func:`hst_comparison`): HST's earthshine in V against the angle above the
bright limb is read from a CSV file with columns ``limb_angle_deg, v_mag_per_arcsec2`` (e.g. the
WFC3 Instrument Handbook's fig. 9.2 digitised; the paper used the STIS handbook's fig. 6.2, the
same curve; the handbook's values are not bundled).  The paper's conclusion (sect. 3.3): CSST must
stay at least 70 deg from the bright limb to see HST's earthshine at 20 deg, HST's own limit.
Here: the limb angle at which the median of CSST's earthshine over the scenario's sunlit-limb
pointings, in 10 deg bins of the limb angle, falls to HST's value at 20 deg.  The HST curve is
in Vega V magnitudes, CSST's in AB V: V_AB - V_Vega = 0.02 mag (Bessell & Murphy 2012), far below
the comparison's scatter.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from straylight.config import Campaign
from straylight.errors import InputError
from straylight.model import BackgroundModel
from straylight.sky.observing import sample_geometry, scene
from straylight.sky.vectors import radec_to_unit

__all__ = [
    "SCENARIO_TIME",
    "HST_BRIGHT_LIMB_LIMIT_DEG",
    "LIMB_BIN_DEG",
    "PhaseSampling",
    "earthshine_scenario",
    "sunlit_limb",
    "read_hst_curve",
    "binned_median_mag",
    "binned_median",
    "crossing_angle_deg",
    "hst_comparison",
    "plot_earthshine_scenario",
]

SCENARIO_TIME = "2026-01-01T00:50:00"
#: HST's own bright-limb limit in the sunlit region (paper sect. 3.3), deg
HST_BRIGHT_LIMB_LIMIT_DEG = 20.0
#: width of the limb-angle bins of CSST's median earthshine, deg
LIMB_BIN_DEG = 10.0


@dataclass(frozen=True)
class PhaseSampling:
    """How the tail's calibration samples the sunlit Earth: orbital phases every ``raan_step_deg``
    in the node and ``u_step_deg`` in the argument of latitude (deg), pointings at HEALPix
    ``nside``, the earthshine computed at the tails ``tails_log10`` (log10 PST at 90 deg, dex)
    and interpolated between them, at ``time`` (UTC, ISO 8601)."""

    raan_step_deg: float
    u_step_deg: float
    nside: int
    tails_log10: tuple
    time: str = SCENARIO_TIME


def earthshine_scenario(campaign: Campaign, time: str = SCENARIO_TIME, band: str = "V") -> dict:
    """The sect. 3.3 scenario: CSST's earthshine at ``time`` on the grid of pointings (RA 0-345 deg,
    Dec -75 to +75 deg, 15 deg steps).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its orbit, Earth and instrument).
    time : str
        UTC time, ISO 8601.
    band : str
        Band name.

    Returns
    -------
    dict
        Per pointing (arrays of shape (n,)): ``ra_deg``, ``dec_deg``, ``earth_limb_angle_deg``
        and ``bright_limb_angle_deg`` (deg), ``limb_is_bright``, the earthshine (total, direct,
        via the door) in e-/s/pix, the earthshine and the zodiacal light in AB mag/arcsec2; and
        ``band``, ``time``.
    """
    ra, dec = np.meshgrid(np.arange(0.0, 346.0, 15.0), np.arange(-75.0, 76.0, 15.0), indexing="ij")
    ra, dec = ra.ravel(), dec.ravel()
    sc = scene(campaign.orbit, time)
    g = sample_geometry(sc, ra, dec, campaign.earth.radius_km, campaign.constraints, grid=True)  # (1, P)
    g = {k: np.asarray(v)[0] for k, v in g.items()}
    sat = np.broadcast_to(sc.satellite_km[0], (ra.size, 3))
    bodies = {k: np.broadcast_to(v[0], (ra.size, 3)) for k, v in sc.bodies_km.items()}
    model = BackgroundModel(campaign)
    comps = model.evaluate(sat, bodies, radec_to_unit(ra, dec), g, [band])[band]
    return {
        "ra_deg": ra,
        "dec_deg": dec,
        "earth_limb_angle_deg": g["earth_limb_angle_deg"],
        "bright_limb_angle_deg": g["bright_limb_angle_deg"],
        "limb_is_bright": g["limb_is_bright"],
        "earthshine_e_per_s_per_pix": comps["earthshine"],
        "earthshine_direct_e_per_s_per_pix": comps["earthshine_direct"],
        "earthshine_door_e_per_s_per_pix": comps["earthshine_door"],
        "earthshine_mag_per_arcsec2": model.mag_per_arcsec2(comps["earthshine"], band),
        "zodiacal_mag_per_arcsec2": model.mag_per_arcsec2(comps["zodiacal"], band),
        "band": band,
        "time": time,
    }


def sunlit_limb(result: dict) -> np.ndarray:
    """The scenario's pointings in the sunlit region: nearest limb bright, above it.

    Parameters
    ----------
    result : dict
        A scenario's result (``limb_is_bright``, ``earth_limb_angle_deg`` in deg).
    """
    return result["limb_is_bright"] & (result["earth_limb_angle_deg"] > 0)


def read_hst_curve(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """HST's earthshine curve: (angle above the bright limb, deg; V mag/arcsec2), sorted by
    angle, from a CSV with columns ``limb_angle_deg, v_mag_per_arcsec2``.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.
    """
    from astropy.table import Table

    p = Path(path)
    if not p.is_file():
        raise InputError(f"--hst-curve: {p} does not exist")
    try:
        t = Table.read(p, format="ascii.csv", comment="#")
    except Exception as exc:
        raise InputError(f"{p}: cannot read the HST curve ({exc})") from exc
    missing = [c for c in ("limb_angle_deg", "v_mag_per_arcsec2") if c not in t.colnames]
    if missing:
        raise InputError(f"{p}: missing column(s) {', '.join(missing)}; have {', '.join(t.colnames)}")
    angle, mag = np.asarray(t["limb_angle_deg"], float), np.asarray(t["v_mag_per_arcsec2"], float)
    bad = ~(np.isfinite(angle) & np.isfinite(mag))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{p}: row {i + 1}: limb_angle_deg = {angle[i]}, v_mag_per_arcsec2 = {mag[i]}: must be finite"
        )
    order = np.argsort(angle)
    return angle[order], mag[order]


def binned_median_mag(
    result: dict, bin_deg: float = LIMB_BIN_DEG
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CSST's median earthshine (mag/arcsec2) over the sunlit-limb pointings in bins of the limb
    angle: (bin centres, deg; medians; pointings per bin), bins without pointings left out.

    Parameters
    ----------
    result : dict
        A scenario's result.
    bin_deg : float, optional
        The bins' width in limb angle, deg (default :data:`LIMB_BIN_DEG`).
    """
    sel = sunlit_limb(result)
    return binned_median(
        result["bright_limb_angle_deg"][sel], result["earthshine_mag_per_arcsec2"][sel], bin_deg
    )


def binned_median(limb_deg, mag, bin_deg: float = LIMB_BIN_DEG) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Medians of ``mag`` in bins of ``limb_deg`` over 0-180 deg.

    Parameters
    ----------
    limb_deg : ndarray, shape (n,)
        Limb angles, deg.
    mag : ndarray, shape (n,)
        Surface brightness, mag/arcsec2.
    bin_deg : float
        Bin width, deg.

    Returns
    -------
    centres : ndarray
        The centres of the bins that hold samples, deg.
    medians : ndarray
        Their medians, mag/arcsec2.
    counts : ndarray of int
        Their sample counts.
    """
    limb, mag = np.asarray(limb_deg, float), np.asarray(mag, float)
    edges = np.arange(0.0, 180.0 + bin_deg, bin_deg)
    which = np.digitize(limb, edges) - 1
    centres, medians, counts = [], [], []
    for k in range(edges.size - 1):
        m = mag[which == k]
        if m.size:
            centres.append(0.5 * (edges[k] + edges[k + 1]))
            medians.append(float(np.median(m)))
            counts.append(m.size)
    return np.array(centres), np.array(medians), np.array(counts, int)


def crossing_angle_deg(centres_deg, median_mag, level_mag) -> float:
    """The limb angle (deg) at which the binned median earthshine first falls to ``level_mag``
    (becomes at least as faint), linear in magnitude between bin centres; NaN if it never does,
    the first centre if it already is there.

    Parameters
    ----------
    centres_deg : ndarray
        Bin centres, limb angle, deg, increasing.
    median_mag : ndarray
        The binned median earthshine, mag/arcsec2.
    level_mag : float
        The level, mag/arcsec2.
    """
    c, m = np.asarray(centres_deg, float), np.asarray(median_mag, float)
    fainter = np.flatnonzero(m >= level_mag)
    if fainter.size == 0:
        return float("nan")
    k = int(fainter[0])
    if k == 0:
        return float(c[0])
    return float(c[k - 1] + (level_mag - m[k - 1]) / (m[k] - m[k - 1]) * (c[k] - c[k - 1]))


def hst_comparison(result: dict, hst_curve: str | Path) -> dict:
    """The paper's CSST-versus-HST comparison (sect. 3.3) for a scenario ``result`` (V band):
    HST's earthshine at its 20 deg limit, interpolated on the curve, and the limb angle at which
    CSST's binned median earthshine falls to it.

    Parameters
    ----------
    result : dict
        A V-band scenario's result.
    hst_curve : str or pathlib.Path
        HST's earthshine curve (:func:`read_hst_curve`).
    """
    angle, mag = read_hst_curve(hst_curve)
    if not angle[0] <= HST_BRIGHT_LIMB_LIMIT_DEG <= angle[-1]:
        raise InputError(
            f"{hst_curve}: limb_angle_deg covers {angle[0]:g}-{angle[-1]:g} deg; it must include "
            f"{HST_BRIGHT_LIMB_LIMIT_DEG:g} deg"
        )
    hst_20 = float(np.interp(HST_BRIGHT_LIMB_LIMIT_DEG, angle, mag))
    centres, medians, counts = binned_median_mag(result)
    return {
        "hst_curve": str(hst_curve),
        "hst_limb_angle_deg": HST_BRIGHT_LIMB_LIMIT_DEG,
        "hst_v_mag_per_arcsec2": hst_20,
        "csst_crossing_limb_angle_deg": crossing_angle_deg(centres, medians, hst_20),
        "paper_crossing_limb_angle_deg": 70.0,
        "band": result["band"],
        "time": result["time"],
        "limb_bin_deg": LIMB_BIN_DEG,
        "bin_centres_deg": centres.tolist(),
        "csst_median_mag_per_arcsec2": medians.tolist(),
        "pointings_per_bin": counts.tolist(),
    }


def plot_earthshine_scenario(
    result: dict, out_png: str | Path, hst_curve: str | Path | None = None, comparison: dict | None = None
) -> None:
    """The paper's fig. (sect. 3.3): CSST's earthshine against the bright-limb angle, its binned
    median, the zodiacal light at the same pointings, and HST's curve when given.

    Parameters
    ----------
    result : dict
        A scenario's result.
    out_png : str or pathlib.Path
        The PNG written.
    hst_curve : str or pathlib.Path, optional
        HST's earthshine curve (:func:`read_hst_curve`), drawn when given.
    comparison : dict, optional
        :func:`hst_comparison`'s result, marked when given.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sel = sunlit_limb(result)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.scatter(
        result["bright_limb_angle_deg"][sel],
        result["earthshine_mag_per_arcsec2"][sel],
        s=12,
        label=f"CSST earthshine (direct + door), {result['band']}",
    )
    centres, medians, _ = binned_median_mag(result)
    ax.plot(centres, medians, "b-", lw=1.5, label=f"CSST median ({LIMB_BIN_DEG:g} deg bins)")
    ax.scatter(
        result["bright_limb_angle_deg"][sel],
        result["zodiacal_mag_per_arcsec2"][sel],
        s=6,
        c="grey",
        label="zodiacal light (same pointings)",
    )
    if hst_curve:
        angle, mag = read_hst_curve(hst_curve)
        ax.plot(angle, mag, "r-", label="HST earthshine (WFC3 IHB fig. 9.2, V)")
    if comparison:
        level, cross = comparison["hst_v_mag_per_arcsec2"], comparison["csst_crossing_limb_angle_deg"]
        ax.axhline(
            level,
            color="r",
            ls=":",
            lw=1,
            label=f"HST at {comparison['hst_limb_angle_deg']:g} deg: {level:.2f}",
        )
        if np.isfinite(cross):
            ax.axvline(
                cross, color="b", ls=":", lw=1, label=f"CSST reaches it at {cross:.1f} deg (paper: 70)"
            )
    ax.invert_yaxis()
    ax.set_xlabel("angle above the bright Earth limb (deg)")
    ax.set_ylabel("surface brightness (mag / arcsec$^2$)")
    ax.set_title(f"Earthshine scenario {result['time']} UTC (seed paper sect. 3.3)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_png, dpi=120)
    plt.close(fig)


def _median_crossing(crossing_deg) -> float:
    """The median crossing, a phase that never crosses counting as beyond every angle."""
    return _percentiles(crossing_deg, (50,))["p50"]


def _percentiles(values, q=(5, 16, 50, 84, 95)) -> dict:
    """Percentiles (numpy's linear) of ``values`` with NaN counted as +inf; next to an
    infinite value, the nearer rank's value."""
    x = np.sort(np.where(np.isnan(values), np.inf, np.asarray(values, float)))
    out = {}
    for k in q:
        pos = k / 100.0 * (x.size - 1)
        lo, hi = int(np.floor(pos)), int(np.ceil(pos))
        a, b = x[lo], x[hi]
        if a == b or hi == lo:
            out[f"p{k}"] = float(a)
        elif np.isfinite(a) and np.isfinite(b):
            out[f"p{k}"] = float(a + (pos - lo) * (b - a))
        else:  # next to an infinite value: the nearer rank
            out[f"p{k}"] = float(a if pos - lo < 0.5 else b)
    return out
