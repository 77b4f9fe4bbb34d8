"""`straylight sky --input pointings --out table.parquet`: values, and bad rows.

Reference values: `straylight sky` for each row, one sample at a time."""

import json

import numpy as np
import pytest
from conftest import run_cli, run_clis


def test_table_matches_single_sample_sky(tmp_path, default_tables):
    import pyarrow.parquet as pq

    rows = [
        ("2026-01-01T00:50:00", 150.0, 40.0),
        ("2026-01-01T05:00:00", 270.0, 66.5),
        ("2026-01-01T05:00:00", 359.99, -89.99),
    ]
    p = tmp_path / "pointings.csv"
    p.write_text("time,ra,dec\n" + "\n".join(f"{t},{r},{d}" for t, r, d in rows) + "\n")
    out = tmp_path / "table.parquet"
    # the table and each row's single-sample command, side by side
    r, *singles = run_clis(
        ("sky", "--input", p, "--out", out, "--bands", "g,y"),
        *(
            ("sky", "--time", tm, "--ra", ra, "--dec", dec, "--bands", "g,y", "--json")
            for tm, ra, dec in rows
        ),
    )
    assert r.returncode == 0, r.stderr
    t = pq.read_table(out).to_pydict()
    assert len(t["time"]) == 3
    for i, one in enumerate(singles):
        assert one.returncode == 0, one.stderr
        rec = json.loads(one.stdout)
        assert t["observable"][i] == rec["observable"]
        for b in ("g", "y"):
            for c in ("zodiacal", "earthshine", "moon", "sun", "total"):
                assert t[f"{c}_{b}"][i] == pytest.approx(
                    rec["bands"][b][c]["e_per_s_per_pix"], rel=1e-6, abs=1e-12
                )
            assert np.isfinite(t[f"limit_mag_{b}"][i])
            assert t[f"limit_mag_{b}"][i] == pytest.approx(rec["bands"][b]["limit_mag"], abs=1e-9)
    # every physical column carries its unit (Parquet field metadata `unit`)
    schema = pq.read_schema(out)
    unit = {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in schema}
    assert unit["total_g"] == unit["zodiacal_y"] == "electron / (s pixel)"
    assert unit["total_mag_per_arcsec2_g"] == "mag(AB) arcsec-2" and unit["limit_mag_y"] == "mag(AB)"
    assert unit["ra_deg"] == unit["sun_angle_deg"] == "deg" and unit["observable"] == ""


@pytest.mark.parametrize(
    "content, message",
    [
        ("time,ra,dec\n2026-01-01T00:00:00,10,nan\n", "row 1: dec = nan is not finite"),
        ("time,ra,dec\n2026-01-01T00:00:00,10,95\n", "row 1: dec = 95.0 outside [-90, 90] deg"),
        ("time,ra\n2026-01-01T00:00:00,10\n", "missing column 'dec'"),
        ("time,ra,dec\n2026-13-45T00:00:00,10,5\n", "row 1: time"),
        ("time,ra,dec\n", "no rows"),
    ],
)
def test_bad_rows_name_file_row_field_and_value(tmp_path, content, message):
    p = tmp_path / "bad.csv"
    p.write_text(content)
    out = tmp_path / "t.parquet"
    r = run_cli("sky", "--input", p, "--out", out)
    assert r.returncode == 2, r.stderr
    assert message in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_distinct_times_equal_numpys_unique_over_the_pairs():
    """pointing_table computes the scene once per distinct (jd1, jd2) pair: the same grouping as
    numpy's unique over the pairs (first index of each, and each sample's group), with repeats,
    equal jd1 and jd2 differing by one ulp."""
    from straylight.model.samples import distinct_times

    rng = np.random.default_rng(5)
    jd1 = rng.choice([2461041.5, 2461042.5, 2461043.5], 500)
    jd2 = rng.choice([0.0, 0.25, np.nextafter(0.25, 1.0), -0.125], 500)
    first, inverse = distinct_times(jd1, jd2)
    pairs = np.stack([jd1, jd2], axis=-1)
    ref, ref_first, ref_inverse = np.unique(pairs, axis=0, return_index=True, return_inverse=True)
    np.testing.assert_array_equal(pairs[first], ref)
    np.testing.assert_array_equal(inverse, ref_inverse.reshape(-1))
    np.testing.assert_array_equal(pairs[first][inverse], pairs)
