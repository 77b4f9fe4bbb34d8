"""`straylight visibility --targets`: names resolve to the packaged fields' published centres and
to the star catalog's positions; all targets evaluated together give each target what
`visibility` gives it alone; the summary's percentiles are numpy's; a bad row is one line, exit 2."""

import numpy as np
import pytest
from conftest import run_cli


def _csv(tmp_path, text, name="targets.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_packaged_fields_resolve_to_their_published_centres(tmp_path):
    """COSMOS: 10h00m28.6s +02d12m21.0s (Scoville et al. 2007, ApJS 172, 1); GOODS-S is the
    CDF-S aim point 03h32m28.0s -27d48m30s (Giacconi et al. 2002, ApJS 139, 369); NGC 253
    00h47m33.13s -25d17m17s (Hubble Heritage): the rows of straylight/data/extragalactic_fields.csv,
    converted here by hand (15 deg per hour)."""
    from straylight.planning.target_names import read_targets

    t = read_targets(_csv(tmp_path, "name,ra,dec\nCOSMOS,,\ngoods-s,,\nNGC253,,\nmine,10.5,-3.25\n"))
    assert t.names == ["COSMOS", "goods-s", "NGC253", "mine"]
    assert t.ra_deg == pytest.approx(
        [15 * (10 + 28.6 / 3600), 15 * (3 + 32 / 60 + 28.0 / 3600), 15 * (47 / 60 + 33.13 / 3600), 10.5],
        abs=1e-9,
    )
    assert t.dec_deg == pytest.approx(
        [2 + 12 / 60 + 21.0 / 3600, -(27 + 48 / 60 + 30 / 3600), -(25 + 17 / 60 + 17 / 3600), -3.25], abs=1e-9
    )
    assert t.source[0].startswith("field COSMOS: Scoville et al. 2007") and t.source[3] == "input"
    assert t.files == ["COSMOS", "goods-s", "NGC253", "mine"]


def test_star_names_give_the_catalog_position_as_image_star_does(tmp_path, campaign):
    """A HIP number (three spellings) and an IAU name give the row `straylight image --star`
    finds in the campaign's default catalog (Sirius = HIP 32349, IAU WGSN list)."""
    from straylight.catalog.campaign_catalog import default_catalog_path
    from straylight.catalog.star_table import read_star_table
    from straylight.cli.image import _read_source_ids, _resolve_star
    from straylight.planning.target_names import read_targets

    cat = default_catalog_path(campaign)
    t = read_targets(_csv(tmp_path, "name,ra,dec\nSirius,,\nHIP 32349,,\n32349,,\nVega,,\n"), cat)
    ra, dec, _ = read_star_table(cat, "g")
    ids = _read_source_ids(cat)
    sirius = _resolve_star({"path": cat}, ids, "Sirius")
    vega = _resolve_star({"path": cat}, ids, "HIP 91262")
    assert t.ra_deg[:3] == pytest.approx([ra[sirius] % 360.0] * 3, abs=1e-12)
    assert t.dec_deg[:3] == pytest.approx([dec[sirius]] * 3, abs=1e-12)
    assert (t.ra_deg[3], t.dec_deg[3]) == pytest.approx((ra[vega], dec[vega]), abs=1e-12)
    assert t.source[1] == f"catalog: HIP 32349 ({cat.name})"


@pytest.mark.parametrize(
    "text, fragment",
    [
        (
            "name,ra,dec\nCOSMOS,,\nNowhere Field,,\n",
            "row 2 (line 3): name 'Nowhere Field' is neither a packaged",
        ),
        ("name,ra,dec\nA,10,\n", "row 1 (line 2): name 'A': give both ra and dec"),
        ("name,ra,dec\nA,10,95\n", "row 1 (line 2): name 'A': dec = 95.0 outside [-90, 90] deg"),
        ("name,ra,dec\nA,ten,5\n", "row 1 (line 2): name 'A': ra = 'ten' is not a number"),
        ("name,ra,dec\n,10,5\n", "row 1 (line 2): name is empty"),
        ("name,ra\nA,10\n", "missing column 'dec'"),
        ("name,ra,dec\nM 31,,\nM_31,1,2\n", "row 2 (line 3): name 'M_31' gives the file name"),
        ("# only a comment\n", "no header and no rows"),
    ],
)
def test_bad_target_rows_one_line_exit_2(tmp_path, text, fragment):
    """Each refusal names the file, the row and the value, before any folder is made."""
    p = _csv(tmp_path, text)
    out = tmp_path / "out"
    r = run_cli(
        "visibility", "--targets", p, "--band", "g", "--start", "2026-01-01", "--end", "2026-01-02",
        "--out", out, cwd=tmp_path,
    )  # fmt: skip
    assert r.returncode == 2, r.stdout + r.stderr
    err = r.stderr.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert str(p) in err and fragment in err, err
    assert not out.exists()


@pytest.fixture(scope="module")
def together(campaign, default_tables, tmp_path_factory):
    """Three targets (a packaged field, a position, a position near the ecliptic) over 2026-01-31
    18:00 to 2026-02-01 06:00 UTC at 10 min, so that the summary has two months."""
    from straylight.planning.target_names import read_targets
    from straylight.planning.targets import SampledWindow, targets_visibility

    p = tmp_path_factory.mktemp("targets") / "t.csv"
    p.write_text("name,ra,dec\nCOSMOS,,\nNorth,150.0,30.0\nEcliptic,200.0,-10.0\n")
    t = read_targets(p)
    window = SampledWindow("2026-01-31T18:00:00", "2026-02-01T06:00:00", 600.0)
    return targets_visibility(campaign, t, "g", window, 26.6, batch=100)


def test_targets_together_equal_each_target_alone(together, campaign):
    """Windows, days and every sample's limit equal `visibility` for the target alone (the
    same evaluation path: same floats, so equality is exact)."""
    from straylight.planning.visibility import visibility

    for k, (ra, dec) in enumerate(zip(together["targets"].ra_deg, together["targets"].dec_deg)):
        one = visibility(campaign, ra, dec, "g", "2026-01-31T18:00:00", "2026-02-01T06:00:00", 600.0, 26.6)
        s = one["samples"]
        assert np.array_equal(np.asarray(s["observable"], bool), together["observable"][k])
        assert np.array_equal(np.asarray(s["limit_mag"].value), together["limit_mag"][k])
        assert np.array_equal(
            np.asarray(s["total_e_per_s_per_pix"].value), together["total_e_per_s_per_pix"][k]
        )
        w, wk = one["windows"], together["windows"][k]
        assert len(w) == len(wk)
        assert list(w["start"].isot) == list(wk["start"].isot) and list(w["end"].isot) == list(wk["end"].isot)
        assert np.array_equal(w["duration_h"].value, wk["duration_h"].value)
        d, dk = one["days"], together["days"][k]
        assert list(d["date"]) == list(dk["date"]) == ["2026-01-31", "2026-02-01"]
        for col in ("observable_hours", "limit_mag_best", "hours_deeper_than_threshold"):
            assert np.array_equal(d[col].value, dk[col].value, equal_nan=True), col


def test_summary_is_the_samples_per_month_with_numpys_percentiles(together):
    """Per target and month: hours = observable samples x 10 min; the deepest limit, its time
    and the hours at or above 26.6 mag from the samples; the background's 10/50/90th
    percentiles equal numpy.percentile (linear) over the month's observable samples."""
    s = together["summary"]
    iso = np.array([x[:7] for x in together["time"].isot])
    assert list(s["month_utc"]) == ["2026-01", "2026-02"] * 3
    for row in s:
        k = together["targets"].names.index(row["target"])
        sel = together["observable"][k] & (iso == row["month_utc"])
        assert row["observable_samples"] == sel.sum()
        if not sel.any():  # never observable in the month: no limit, no time, no percentiles
            assert np.isnan(row["limit_best_mag_ab"].value) and row["limit_best_time_utc"] in ("", "--")
            assert np.isnan(row["background_p50_e_per_s_per_pix"].value)
            continue
        assert row["observable_hours_h"].value == pytest.approx(sel.sum() / 6.0, rel=1e-12)
        lim, tot = together["limit_mag"][k][sel], together["total_e_per_s_per_pix"][k][sel]
        assert row["limit_best_mag_ab"].value == lim.max()
        j = np.flatnonzero(sel)[np.argmax(lim)]
        assert row["limit_best_time_utc"] == together["time"][j].isot[:19]
        assert row["hours_deeper_than_threshold_h"].value == pytest.approx(
            (lim >= 26.6).sum() / 6.0, rel=1e-12
        )
        for q in (10, 50, 90):
            assert row[f"background_p{q}_e_per_s_per_pix"].value == pytest.approx(
                np.percentile(tot, q), rel=1e-12
            )


def test_cli_targets_writes_summary_and_per_target_tables(tmp_path, default_tables):
    """As a user runs it: names and positions mixed, a folder with the summary, the resolved
    list and each target's windows and days; the printed summary has one line per target and
    month."""
    from astropy.table import Table

    p = _csv(tmp_path, "name,ra,dec\nCOSMOS,,\nNGC 253,,\nmy field,150.0,30.0\n")
    out = tmp_path / "out"
    r = run_cli(
        "visibility", "--targets", p, "--band", "g", "--start", "2026-01-01T00:00:00",
        "--end", "2026-01-01T06:00:00", "--step-min", "20", "--threshold", "26.5", "--out", out,
        timeout=600,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    names = sorted(f.name for f in out.iterdir())
    assert names == sorted(
        ["summary.csv", "targets.csv"]
        + [f"{n}_{k}.csv" for n in ("COSMOS", "NGC_253", "my_field") for k in ("windows", "days")]
    )
    s = Table.read(out / "summary.csv")
    assert len(s) == 3 and list(s["target"]) == ["COSMOS", "NGC 253", "my field"]
    assert "background_p50_e_per_s_per_pix" in s.colnames and "limit_best_mag_ab" in s.colnames
    d = Table.read(out / "NGC_253_days.csv")
    assert d["observable_hours"][0] == pytest.approx(s["observable_hours_h"][1], abs=1e-9)
    assert "2026-01" in r.stdout and "my field" in r.stdout and "e-/s/pix" in r.stdout


def test_per_target_tables_are_the_text_astropy_writes(tmp_path):
    """The windows and days files (written column by column for speed) hold exactly the text
    astropy's CSV writer gives for the same tables, NaN days and an empty window list included."""
    import astropy.units as u
    from astropy.time import Time

    from straylight.planning.targets import _csv_text
    from straylight.planning.visibility import daily_tables, observable_windows

    t0 = Time("2026-01-31T18:00:00", scale="utc")
    t = t0 + np.arange(150) * 600 * u.s
    edges = np.minimum(np.arange(151) * 600.0, 149.5 * 600)  # the last sample cut at the end
    rng = np.random.default_rng(3)
    obs = rng.random((3, 150)) < 0.4
    obs[2] = False
    lim = 26 + rng.random((3, 150))
    tables = observable_windows(obs, t, t0, edges) + daily_tables(obs, lim, t, edges, 26.5)
    assert [len(x) for x in tables[:3]][2] == 0 and np.isnan(tables[5]["limit_mag_best"][0].value)
    for k, table in enumerate(tables):
        path = tmp_path / f"{k}.csv"
        table.write(path, format="ascii.csv")
        assert _csv_text(table) == path.read_text(), k


def test_monthly_percentiles_are_numpys_on_spread_samples():
    """On backgrounds that all differ (random, two months, some samples not observable), each
    month's 10/50/90th percentiles equal numpy.percentile (linear interpolation) over that
    month's observable samples, and a month with none gives NaN."""
    import astropy.units as u
    from astropy.time import Time

    from straylight.planning.target_names import Targets
    from straylight.planning.targets import monthly_summary

    t = Time("2026-01-31T00:00:00", scale="utc") + np.arange(96) * 1800 * u.s  # to Feb 1 23:30
    rng = np.random.default_rng(7)
    obs = rng.random((2, 96)) < 0.6
    obs[1, 48:] = False  # target 1 never observable in February
    total = rng.lognormal(-2.0, 0.5, (2, 96))
    lim = 26 + rng.random((2, 96))
    tg = Targets(["a", "b"], ["a", "b"], np.array([1.0, 2.0]), np.array([3.0, 4.0]), ["input"] * 2)
    s = monthly_summary(tg, "g", obs, lim, total, t, np.arange(97) * 1800.0)
    month = np.array([x[:7] for x in t.isot])
    for row in s:
        k = tg.names.index(row["target"])
        sel = obs[k] & (month == row["month_utc"])
        for q in (10, 50, 90):
            got = row[f"background_p{q}_e_per_s_per_pix"].value
            if sel.any():
                assert got == pytest.approx(np.percentile(total[k][sel], q), rel=1e-12)
            else:
                assert np.isnan(got)
    assert np.isnan(s["limit_best_mag_ab"][3].value) and s["observable_hours_h"][3].value == 0.0
