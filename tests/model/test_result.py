"""One result type (straylight.model.result.BackgroundResult) and its three shapes: the table
(astropy QTable with units), the Dataset (xarray, ``units`` and ``long_name`` on every
variable) and the JSON record must give the same numbers in the same units, sample by sample.

Reference numbers: each sample's total is the sum of its components (the seed paper's total
background, sect. 2), to float64 rounding (1e-12 relative); a component's surface brightness is
the band's zero point - 2.5 log10(rate) (AB, per arcsec2 at 1 e-/s/pix)."""

import astropy.units as u
import numpy as np
import pytest

from straylight.model import BackgroundModel
from straylight.model.pointing import background_result
from straylight.model.registry import component_names
from straylight.model.samples import SampleBatch
from straylight.planning.pointings import with_limits
from straylight.sky.observing import scene
from straylight.sky.vectors import radec_to_unit

RATE = u.electron / (u.s * u.pix)


@pytest.fixture(scope="module")
def result(campaign):
    model = BackgroundModel(campaign)
    times = ["2026-01-01T00:50:00", "2026-01-01T03:10:00"]
    sc = scene(campaign.orbit, times)
    ra, dec = np.array([10.0, 120.0, 250.0, 300.0]), np.array([-20.0, 5.0, 60.0, -75.0])
    los = np.tile(radec_to_unit(ra, dec), (2, 1))
    index = np.repeat([0, 1], 4)
    bands = list(campaign.bands) + ["V"]
    res = background_result(model, SampleBatch(sc, los, index), bands, in_field_bands=bands)
    return with_limits(res, campaign).at(sc.times[index], np.tile(ra, 2), np.tile(dec, 2))


def test_table_dataset_and_record_agree(result):
    """Every component, magnitude, limit and angle is the same number in the table, the Dataset
    and the record (exactly: one array behind the three), in the units each states."""
    table, ds = result.to_table(), result.to_dataset()
    assert len(table) == ds.sizes["sample"] == result.n == 8
    assert list(ds["band"].values) == list(result.bands)
    for i in range(result.n):
        rec = result.to_record(i)
        assert rec["observable"] == bool(table["observable"][i]) == bool(ds["observable"].values[i])
        g = rec["geometry"]
        for name in ("sun_angle", "moon_angle", "earth_limb_angle"):
            assert g[f"{name}_deg"] == table[name][i].to_value(u.deg) == ds[f"{name}_deg"].values[i]
        for ib, b in enumerate(result.bands):
            entry = rec["bands"][b]
            for c in component_names(total=True):
                e = entry[c]["e_per_s_per_pix"]
                assert table[f"{c}_{b}"][i].to_value(RATE) == e == ds[c].values[i, ib]
                m = table[f"{c}_mag_{b}"][i].to_value(u.mag / u.arcsec**2)
                assert entry[c]["mag_per_arcsec2"] == (m if np.isfinite(m) else None)
            assert (
                entry["mag_zero_point"]
                == table.meta["mag_zero_point"][b].value
                == ds["zero_point"].values[ib]
            )
            if b == "V":
                assert entry["limit_mag"] is None and f"limit_mag_{b}" not in table.colnames
                assert np.isnan(ds["limit_mag"].values[i, ib])
            else:
                assert (
                    entry["limit_mag"]
                    == table[f"limit_mag_{b}"][i].to_value(u.mag)
                    == ds["limit_mag"].values[i, ib]
                )


def test_the_shapes_state_their_units_and_the_total_is_the_sum(result):
    """The table's rates are in electron / (s pix) and its magnitudes in mag / arcsec2; every
    Dataset variable carries ``units`` (parsed by astropy to the same unit) and ``long_name``;
    the total is the sum of the components (1e-12) and its magnitude the zero point - 2.5
    log10(total)."""
    table, ds = result.to_table(), result.to_dataset()
    for name in ds.data_vars:
        assert {"units", "long_name"} <= set(ds[name].attrs), name
    comps = [c for c in component_names(total=True) if c != "total"]
    for ib, b in enumerate(result.bands):
        assert table[f"total_{b}"].unit == RATE == u.Unit(ds["total"].attrs["units"])
        assert table[f"total_mag_{b}"].unit == u.mag / u.arcsec**2
        total = ds["total"].values[:, ib]
        np.testing.assert_allclose(total, sum(ds[c].values[:, ib] for c in comps), rtol=1e-12, atol=0)
        np.testing.assert_allclose(
            table[f"total_mag_{b}"].value, result.zero_points[b] - 2.5 * np.log10(total), rtol=0, atol=1e-12
        )
    assert u.Unit(ds["zero_point"].attrs["units"]) == u.mag / u.arcsec**2
