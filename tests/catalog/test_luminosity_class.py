"""Luminosity classes of Hipparcos stars from their parallaxes, for the template choice.

Reference values: the published spectral types of bright stars (SIMBAD / the Bright Star
Catalogue: Betelgeuse M1-2 Ia-Iab, Antares M1.5 Iab-Ib, Rigel B8 Ia, Deneb A2 Ia, Sirius A1 V,
Vega A0 V, Arcturus K1.5 III, Aldebaran K5 III), Torres (2010) for the bolometric corrections."""

import numpy as np
import pytest
import yaml
from conftest import REPO

# HIP number -> the luminosity class its published spectral type gives (Ia/Iab/Ib -> I)
BRIGHT = {
    27989: "I",  # Betelgeuse, M1-2 Ia-Iab
    80763: "I",  # Antares, M1.5 Iab-Ib
    24436: "I",  # Rigel, B8 Ia
    102098: "I",  # Deneb, A2 Ia
    32349: "V",  # Sirius, A1 V
    91262: "V",  # Vega, A0 V
    69673: "III",  # Arcturus, K1.5 III
    21421: "III",  # Aldebaran, K5 III
}


@pytest.fixture(scope="module")
def bright_catalog():
    from straylight.catalog.build import TemplatePhotometry, build_catalog
    from straylight.catalog.hipparcos import hipparcos_stars
    from straylight.catalog.sed import load_pickles
    from straylight.optics.bandpass import load_band

    inst = yaml.safe_load((REPO / "config" / "instruments" / "csst.yaml").read_text())
    responses = {b: load_band(inst, b).response for b in inst["bands"]}
    hip = hipparcos_stars()
    keep = np.isin(hip["source_id"], list(BRIGHT))
    stars = {k: v[keep] for k, v in hip.items()}
    return build_catalog(stars, TemplatePhotometry(load_pickles(), responses))


def test_hip2_has_no_spectral_types():
    """hip2.dat (van Leeuwen 2007, CDS I/311) is all numbers: 26 columns and the 15 of the upper
    triangular weight matrix, no spectral type; the class must come from the parallax."""
    from straylight.catalog.hipparcos import hip2_path

    with open(hip2_path()) as f:
        fields = f.readline().split()
    assert len(fields) == 26 + 15
    assert all(np.isfinite(float(x)) for x in fields)


def test_flower_torres_bolometric_correction_of_the_sun():
    """Torres (2010, AJ 140, 1158, sect. 3): Flower's (1996) scale gives BC_V,sun = -0.080 at
    Teff,sun = 5777 K (hence M_bol,sun = 4.73 with M_V,sun = 4.81)."""
    from straylight.catalog.luminosity import M_BOL_SUN, bc_v_flower

    assert float(bc_v_flower(5777.0)) == pytest.approx(-0.080, abs=0.005)
    assert M_BOL_SUN == pytest.approx(4.81 - 0.08)


def test_template_absolute_magnitudes_order_the_classes():
    """The templates' M_V (de Jager & Nieuwenhuijzen 1987 log L and Teff, Flower-Torres BC):
    G2V is the Sun's 4.81 (Willmer 2018, ApJS 236, 47) within 0.4 mag; at M2 the supergiant is
    more than 4 mag brighter than the giant, which is more than 7 mag brighter than the dwarf."""
    from straylight.catalog.luminosity import template_abs_v_mag

    g2v, m2i, m2iii, m2v = template_abs_v_mag(["G2V", "M2I", "M2III", "M2V"])
    assert g2v == pytest.approx(4.81, abs=0.4)
    assert m2i < m2iii - 4.0 and m2iii < m2v - 7.0


def test_supergiants_get_supergiant_templates(bright_catalog):
    """Betelgeuse (M1-2 Ia-Iab: M_V = -5.5 from V 0.45 and its 6.55 mas parallax) gets the
    library's M supergiant, M2I, and log g 1.0 (the supergiants' nominal value), not a dwarf
    (M3V, log g 4.5, before); every bright star of BRIGHT gets a template of its published class,
    flagged as chosen by the parallax."""
    from straylight.catalog.build import FLAG_CLASS_FROM_PARALLAX
    from straylight.catalog.sed import parse_spectral_type

    cat = bright_catalog
    got = {int(h): str(t) for h, t in zip(cat["source_id"], cat["template"])}
    assert got[27989] == "M2I"
    k = int(np.flatnonzero(cat["source_id"] == 27989)[0])
    assert cat["logg"][k] == pytest.approx(1.0)
    for hip, lc in BRIGHT.items():
        assert parse_spectral_type(got[hip])[2] == lc, (hip, got[hip])
    assert np.all(cat["flags"] & FLAG_CLASS_FROM_PARALLAX)
    k = int(np.flatnonzero(cat["source_id"] == 32349)[0])
    assert cat["logg"][k] == pytest.approx(4.5)


def test_without_a_parallax_the_colour_match_keeps_to_dwarfs_and_giants():
    """A star with no measured luminosity (NaN M_V, e.g. a Gaia row or a parallax below 5 sigma)
    is matched on colour among V, IV and III only; with an M_V it may take a supergiant."""
    from straylight.catalog.luminosity import choose_templates

    colour = np.array([1.0, 1.02, 1.04, 1.5])
    classes = np.array(["I", "III", "V", "V"])
    abs_v = np.array([-6.0, 0.5, 6.0, 8.0])
    idx, by_lum = choose_templates(
        colour, classes, abs_v, np.array([1.0, 1.0, 1.0]), np.array([np.nan, -5.0, 5.5])
    )
    assert idx.tolist() == [1, 0, 2]
    assert by_lum.tolist() == [False, True, True]
