"""Reproductions of the paper's scenarios.

:func:`earthshine_scenario` - sect. 3.3: at 2026-01-01 00:50 UTC, pointings on a grid RA 0-345 deg
(15 deg steps) x Dec -75 to +75 deg (15 deg steps); CSST earthshine (direct + door) per band
against the Earth-limb angle, for pointings in the sunlit region (nearest limb bright).  The HST
curve of the STIS Instrument Handbook (Fig. 6.2) can be overlaid from a CSV file with columns
``limb_angle_deg, v_mag_per_arcsec2`` (the handbook's values are not bundled).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .components import ComponentModel
from .config import Campaign
from .geometry import radec_to_unit
from .sky import sample_geometry, scene

SCENARIO_TIME = "2026-01-01T00:50:00"


def earthshine_scenario(campaign: Campaign, time: str = SCENARIO_TIME, band: str = "V") -> dict:
    ra, dec = np.meshgrid(np.arange(0.0, 346.0, 15.0), np.arange(-75.0, 76.0, 15.0), indexing="ij")
    ra, dec = ra.ravel(), dec.ravel()
    sc = scene(campaign, time)
    g = sample_geometry(campaign, sc, ra, dec, grid=True)  # (1, P)
    g = {k: np.asarray(v)[0] for k, v in g.items()}
    sat = np.broadcast_to(sc.satellite_km[0], (ra.size, 3))
    bodies = {k: np.broadcast_to(v[0], (ra.size, 3)) for k, v in sc.bodies_km.items()}
    comps = ComponentModel(campaign).evaluate(sat, bodies, radec_to_unit(ra, dec), g, [band])[band]
    return {
        "ra_deg": ra, "dec_deg": dec,
        "earth_limb_angle_deg": g["earth_limb_angle_deg"],
        "limb_is_bright": g["limb_is_bright"],
        "earthshine_e_per_s_per_pix": comps["earthshine"],
        "earthshine_direct_e_per_s_per_pix": comps["earthshine_direct"],
        "earthshine_door_e_per_s_per_pix": comps["earthshine_door"],
        "earthshine_mag_per_arcsec2": comps["_mag"](comps["earthshine"]),
        "zodiacal_mag_per_arcsec2": comps["_mag"](comps["zodiacal"]),
        "band": band, "time": time,
    }


def plot_earthshine_scenario(result: dict, out_png: str | Path, hst_csv: str | Path | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sel = result["limb_is_bright"] & (result["earth_limb_angle_deg"] > 0)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.scatter(result["earth_limb_angle_deg"][sel], result["earthshine_mag_per_arcsec2"][sel], s=12,
               label=f"CSST earthshine (direct + door), {result['band']}")
    ax.scatter(result["earth_limb_angle_deg"][sel], result["zodiacal_mag_per_arcsec2"][sel], s=6, c="grey",
               label="zodiacal light (same pointings)")
    if hst_csv:
        from astropy.table import Table

        t = Table.read(hst_csv, format="ascii.csv")
        ax.plot(t["limb_angle_deg"], t["v_mag_per_arcsec2"], "r-", label="HST (STIS IHB Fig. 6.2)")
    ax.invert_yaxis()
    ax.set_xlabel("angle above the bright Earth limb (deg)")
    ax.set_ylabel("surface brightness (AB mag / arcsec$^2$)")
    ax.set_title(f"Earthshine scenario {result['time']} UTC (seed paper sect. 3.3)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_png, dpi=120)
    plt.close(fig)
