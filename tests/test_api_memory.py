"""Bounded memory of the API and `straylight sky --input`: samples evaluated in chunks into a
result allocated once; the chunked results equal one chunk's exactly; float32 and a subset of
columns; a run under an address-space cap.

Reference values: the same samples evaluated in one chunk (the code path before chunking)."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

T0 = "2026-01-01T00:00:00"


def _samples(n, seed=1):
    """n random (time within a day, direction uniform on the sphere) samples."""
    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    rng = np.random.default_rng(seed)
    t = Time(T0, scale="utc") + rng.uniform(0, 86400, n) * u.s
    c = SkyCoord(rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n))), unit="deg")
    return t, c


def _assert_tables_equal(a, b):
    from astropy.time import Time

    assert a.colnames == b.colnames
    for name in a.colnames:
        x, y = a[name], b[name]
        if isinstance(x, Time):
            np.testing.assert_array_equal(x.jd1, y.jd1)
            np.testing.assert_array_equal(x.jd2, y.jd2)
            assert x.format == y.format and x.precision == y.precision
            continue
        assert getattr(x, "unit", None) == getattr(y, "unit", None), name
        assert x.info.format == y.info.format and x.info.description == y.info.description, name
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y), err_msg=name)
    assert a.meta["mag_zero_point"] == b.meta["mag_zero_point"]
    assert a.meta["models"] == b.meta["models"]


def test_chunked_table_equals_one_chunk(monkeypatch):
    """5000 samples in chunks of 700 rows (the last one short) equal the same samples in one
    chunk, column by column and bit for bit, with the same units, formats and meta."""
    import straylight
    from straylight.planning import pointings

    t, c = _samples(5000)
    sky = straylight.SkyModel()
    monkeypatch.setattr(pointings, "CHUNK_ROWS", 0)
    whole = sky.background(t, c, bands=["g", "NUV"])
    monkeypatch.setattr(pointings, "CHUNK_ROWS", 700)
    chunked = sky.background(t, c, bands=["g", "NUV"])
    assert len(chunked) == 5000
    # the samples span the constraints: both observable and violated ones, several reasons
    assert 0 < np.sum(chunked["observable"]) < 5000 and len(set(chunked["violations"])) > 3
    _assert_tables_equal(chunked, whole)


def test_float32_and_a_subset_of_columns(monkeypatch):
    """dtype="float32" gives the float64 values rounded to float32 (exactly: the same cast), and
    ``columns`` the chosen columns only, with the same values; an unknown column is refused."""
    import astropy.units as u

    import straylight
    from straylight.planning import pointings

    monkeypatch.setattr(pointings, "CHUNK_ROWS", 300)
    t, c = _samples(1000, seed=2)
    full = straylight.sky_background(t, c, bands=["r"])
    small = straylight.sky_background(t, c, bands=["r"], columns=["time", "total_r", "observable"])
    assert small.colnames == ["time", "total_r", "observable"]
    np.testing.assert_array_equal(small["total_r"].value, full["total_r"].value)
    f32 = straylight.sky_background(t, c, bands=["r"], dtype="float32")
    assert f32["total_r"].dtype == np.float32 and f32["total_r"].unit == u.electron / (u.s * u.pix)
    np.testing.assert_array_equal(f32["total_r"].value, full["total_r"].value.astype(np.float32))
    np.testing.assert_array_equal(f32["limit_mag_r"].value, full["limit_mag_r"].value.astype(np.float32))
    with pytest.raises(straylight.InputError, match="unknown column 'total_x'"):
        straylight.sky_background(t, c, bands=["r"], columns=["total_x"])
    with pytest.raises(straylight.InputError, match="dtype"):
        straylight.sky_background(t, c, bands=["r"], dtype="int8")


def test_sky_input_in_chunks_equals_one_chunk(tmp_path, monkeypatch):
    """`sky --input` writes chunk by chunk; the Parquet file reads back equal to one chunk's."""
    import pyarrow.parquet as pq

    from straylight.cli import main
    from straylight.planning import pointings

    t, c = _samples(2500, seed=3)
    csv = tmp_path / "p.csv"
    csv.write_text(
        "time,ra,dec\n"
        + "".join(f"{s},{a:.17g},{d:.17g}\n" for s, a, d in zip(t.isot, c.ra.deg, c.dec.deg, strict=True))
    )
    out = {}
    for rows in (0, 600):
        monkeypatch.setattr(pointings, "CHUNK_ROWS", rows)
        path = tmp_path / f"out{rows}.parquet"
        assert main(["sky", "--input", str(csv), "--out", str(path), "--bands", "g"]) == 0
        out[rows] = pq.read_table(path)
    assert out[600].num_rows == 2500 and pq.ParquetFile(tmp_path / "out600.parquet").num_row_groups == 5
    assert out[600].schema == out[0].schema  # units and metadata alike
    for name in out[0].column_names:  # NaN equal to NaN (pyarrow's equals has them differ)
        a, b = (np.asarray(out[k][name].to_numpy(zero_copy_only=False)) for k in (600, 0))
        np.testing.assert_array_equal(a, b, err_msg=name)


#: the child: a warm model, its address space then capped at what it uses plus the result's size
#: (measured on a smaller call) plus 0.5 GB, then two million samples in one band
_CAPPED = textwrap.dedent(
    """
    import resource, sys
    import numpy as np
    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from astropy.time import Time
    import straylight

    def vm_bytes():
        for line in open("/proc/self/status"):
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024

    n = int(sys.argv[1])
    rng = np.random.default_rng(4)
    t = Time("2026-01-01T00:00:00", scale="utc") + rng.uniform(0, 86400, n) * u.s
    c = SkyCoord(rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n))), unit="deg")
    sky = straylight.SkyModel()
    probe = sky.background(t[:150000], c[:150000], bands=["g"])  # every thread and arena made
    per_row = sum(col.nbytes for col in probe.itercols() if hasattr(col, "nbytes"))
    per_row = (per_row + probe["time"].jd1.nbytes * 2) / len(probe)
    del probe
    cap = vm_bytes() + int(per_row * n) + 2**29
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
    sky.background(t, c, bands=["g"])
    print("ok", per_row, cap)
    """
)


@pytest.mark.slow
def test_two_million_samples_under_an_address_space_cap():
    """Two million samples in one band under RLIMIT_AS = the process's address space after a warm
    call + the result's size (0.37 GB) + 0.5 GB, the bound of the chunked evaluation; before
    it the call took ~0.75 GB beyond its result (max RSS 1.99 GB, from 0.51 GB before the call)
    and failed here with MemoryError (bench/api_memory.py: max RSS 0.98 GB now, from 0.47 GB)."""
    r = subprocess.run(
        [sys.executable, "-c", _CAPPED, "2000000"], capture_output=True, text=True, timeout=3600
    )
    assert r.returncode == 0 and r.stdout.startswith("ok"), r.stdout + r.stderr[-3000:]


def test_memory_per_sample_is_the_tables_own(monkeypatch):
    """Python allocations (tracemalloc) per added sample in one band, between 32,768 and 65,536
    samples (whole chunks, so one chunk's work cancels): the returned table is 186 bytes a row
    (21 float64 columns, the two-part time, the observable flag and the uint8 violations mask),
    within 8; the call's peak is the table's plus under 40 bytes a row (the samples' checked
    copies: UTC time and RA/Dec, 32 bytes); after the call under 24 bytes a row is left (16 are
    measured: the checked UTC time's arrays).  Before: the violations text alone was ~180 bytes a
    row (4-byte characters, as wide as the longest list of names), and 48 bytes a row were left
    after the call (the TT and spherical views astropy caches on the Time and SkyCoord)."""
    import tracemalloc

    import astropy.units as u
    from astropy.time import Time

    import straylight
    from straylight.planning import pointings

    monkeypatch.setattr(pointings, "CHUNK_ROWS", 2**13)
    sky = straylight.SkyModel()
    sky.background(*_samples(1000, seed=5), bands=["g"])  # warm: tables, kernels, threads
    peaks, rows, left = {}, {}, {}
    for n in (2**15, 2**16):
        t, c = _samples(n, seed=6)
        t = Time(T0, scale="utc") + (np.arange(n) % 64) * 10 * u.min  # 64 scenes: quick to compute
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            table = sky.background(t, c, bands=["g"])
            after, peak = tracemalloc.get_traced_memory()
            del table
            left[n] = tracemalloc.get_traced_memory()[0] - before
        finally:
            tracemalloc.stop()
        peaks[n], rows[n] = peak - before, after - before
    per_row, table_row, left_row = ((d[2**16] - d[2**15]) / 2**15 for d in (peaks, rows, left))
    assert table_row == pytest.approx(186, abs=8), (table_row, per_row, left_row)
    assert per_row < table_row + 40, (per_row, table_row, left_row)
    assert left_row < 24, (left_row, table_row, per_row)
