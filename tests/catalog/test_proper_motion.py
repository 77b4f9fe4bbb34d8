"""Star positions carried to the observation's date by their proper motions (images)."""

import numpy as np
import pytest
from astropy.time import Time

from straylight.catalog.hipparcos import HIPPARCOS_EPOCH_YR, read_hip2
from straylight.catalog.star_table import propagate_positions, read_star_table

SIRIUS_HIP = 32349
DATE = Time("2026-01-01T00:00:00", scale="utc")


def _sirius_hip2():
    h = read_hip2()
    k = int(np.flatnonzero(h["hip"] == SIRIUS_HIP)[0])
    return {c: float(h[c][k]) for c in ("ra_deg", "dec_deg", "parallax_mas", "pmra_mas_yr", "pmdec_mas_yr")}


def _sep_arcsec(ra1, dec1, ra2, dec2):
    from astropy.coordinates import SkyCoord

    return float(SkyCoord(ra1, dec1, unit="deg").separation(SkyCoord(ra2, dec2, unit="deg")).arcsec)


def test_sirius_in_2026_matches_astropy_space_motion():
    """Sirius (HIP 32349) from hip2.dat (van Leeuwen 2007: J1991.25, pmRA* -546.05, pmDE
    -1223.14 mas/yr) to 2026-01-01: against astropy's SkyCoord.apply_space_motion (ERFA pmsafe,
    with the hip2 parallax and no radial velocity), within 0.5 arcsec (they agree to < 1 mas).
    The catalog's own J1991.25 position is 46.5 arcsec away (1339 mas/yr x 34.75 yr)."""
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    s = _sirius_hip2()
    ra, dec = propagate_positions(
        [s["ra_deg"]],
        [s["dec_deg"]],
        [s["pmra_mas_yr"]],
        [s["pmdec_mas_yr"]],
        HIPPARCOS_EPOCH_YR,
        DATE.tt.jyear,
    )
    ref = SkyCoord(
        ra=s["ra_deg"] * u.deg,
        dec=s["dec_deg"] * u.deg,
        distance=(s["parallax_mas"] * u.mas).to(u.pc, u.parallax()),
        pm_ra_cosdec=s["pmra_mas_yr"] * u.mas / u.yr,
        pm_dec=s["pmdec_mas_yr"] * u.mas / u.yr,
        radial_velocity=0 * u.km / u.s,
        obstime=Time(HIPPARCOS_EPOCH_YR, format="jyear", scale="tt"),
    ).apply_space_motion(new_obstime=DATE.tt)
    assert _sep_arcsec(ra[0], dec[0], ref.ra.deg, ref.dec.deg) < 0.5
    assert _sep_arcsec(ra[0], dec[0], ref.ra.deg, ref.dec.deg) < 0.005
    assert _sep_arcsec(s["ra_deg"], s["dec_deg"], ra[0], dec[0]) == pytest.approx(46.5, abs=0.2)


def test_sirius_in_2026_matches_simbad_j2000_propagated():
    """SIMBAD's Sirius at J2000 (ICRS 06 45 08.91728 -16 42 58.0171, pm -546.01 -1223.07 mas/yr,
    from van Leeuwen 2007) moved 26 years by its proper motion (small-angle: 0.2 mas of
    curvature over 35 arcsec), against the catalog's J1991.25 position propagated: < 0.5 arcsec."""
    s = _sirius_hip2()
    ra, dec = propagate_positions(
        [s["ra_deg"]],
        [s["dec_deg"]],
        [s["pmra_mas_yr"]],
        [s["pmdec_mas_yr"]],
        HIPPARCOS_EPOCH_YR,
        DATE.tt.jyear,
    )
    ra0 = (6 + 45 / 60 + 8.91728 / 3600) * 15.0
    dec0 = -(16 + 42 / 60 + 58.0171 / 3600)
    dt = DATE.tt.jyear - 2000.0
    ra_simbad = ra0 + -546.01e-3 * dt / 3600.0 / np.cos(np.radians(dec0))
    dec_simbad = dec0 + -1223.07e-3 * dt / 3600.0
    assert _sep_arcsec(ra[0], dec[0], ra_simbad, dec_simbad) < 0.5


def test_star_table_read_at_an_epoch(tmp_path):
    """read_star_table(epoch=...) (what ``straylight image`` calls with DATE-OBS) moves the
    stars of a table with pmra, pmdec and ref_epoch; without epoch, or without those columns,
    the positions are the stored ones.  A star near the pole and a star without proper motion
    (NaN) are carried too."""
    from astropy.table import Table

    s = _sirius_hip2()
    t = Table(
        {
            "ra": [s["ra_deg"], 10.0, 50.0],
            "dec": [s["dec_deg"], 89.99, 5.0],
            "pmra": [s["pmra_mas_yr"], 1000.0, np.nan],
            "pmdec": [s["pmdec_mas_yr"], 0.0, np.nan],
            "ref_epoch": [HIPPARCOS_EPOCH_YR, 2015.5, 2015.5],
            "mag_g": [-1.4, 5.0, 6.0],
        }
    )
    path = tmp_path / "stars.ecsv"
    t.write(path)
    ra, dec, mag = read_star_table(path, "g", epoch=DATE)
    assert _sep_arcsec(ra[0], dec[0], s["ra_deg"], s["dec_deg"]) == pytest.approx(46.5, abs=0.2)
    # 1 arcsec/yr for 10.5 yr near the pole: a great-circle move of 10.5 arcsec
    assert _sep_arcsec(ra[1], dec[1], 10.0, 89.99) == pytest.approx(1.0 * (DATE.tt.jyear - 2015.5), rel=1e-3)
    assert (ra[2], dec[2]) == pytest.approx((50.0, 5.0), abs=1e-12)
    ra_stored, dec_stored, _ = read_star_table(path, "g")
    assert (ra_stored[0], dec_stored[0]) == (s["ra_deg"], s["dec_deg"])
    t.remove_columns(["pmra", "pmdec", "ref_epoch"])
    t.write(tmp_path / "plain.ecsv")
    ra_plain, _, _ = read_star_table(tmp_path / "plain.ecsv", "g", epoch=DATE)
    assert ra_plain[0] == s["ra_deg"]
