"""Benchmark of the compact sky product (sky_compact.zarr): size, error and read speed, beside the
same look-ups through xarray on background.zarr and through straylight.SkyModel.

On a finished campaign's results folder (``--results``, holding background.zarr), prints and
writes bench/results/compact_<campaign>.json:

* per quantisation step (``--steps``): bytes per (time, pixel) sample on disk (seven bands and
  the observability), the error against background.zarr's total over the observable samples
  (per band: rms, p99, p99.9, max; the writer's measurement, in the product's attributes), the
  write's wall and CPU seconds (this process, its threads included) and samples/s;
* with the default step: ``SkyMaps`` opened (s), the first full-sky all-band map (decoding its
  chunk), then warm maps at random times between grid times (median ms), random (time, pixel)
  batches of ``--batch`` samples, all bands, after every chunk is decoded (values/s; a value is
  one band of one sample), and the decoding of every chunk (s);
* opening a year's product: a store of a year's times made of the written product's chunks
  repeated (the opening reads only the metadata and the pixel coordinate, so only its time is
  meaningful);
* the same look-ups through xarray (``open_zarr`` of background.zarr, the total converted to
  mag/arcsec2) and through ``SkyModel`` (the default config; without a star table, as
  bench/api.py, unless ``--skymodel-catalog``): a
  full-sky all-band map at one time and a random batch (``--xarray-batch``, ``--skymodel-batch``);
* the write's wall seconds against the campaign's (``--campaign-wall-s``: e.g. bench/pipeline.py's
  wall to wall, or the Snakemake log's).

Run:  python bench/compact.py --results results/m32 --campaign-wall-s 62.5
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402


def timed(fn):
    """(result, wall seconds, CPU seconds of this process) of fn()."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def year_store(src: Path, dst: Path, n_times: int) -> None:
    """A store of ``n_times`` times made of ``src``'s chunks repeated (for timing the opening)."""
    shutil.copytree(src, dst)
    meta_paths = [dst / "zarr.json", dst / "mag" / "zarr.json", dst / "observable" / "zarr.json"]
    for p in meta_paths:
        meta = json.loads(p.read_text())
        if p.parent == dst:
            meta["attributes"]["n_times"] = n_times
            for k in ("mag", "observable"):
                meta["consolidated_metadata"]["metadata"][k]["shape"][0] = n_times
            meta["consolidated_metadata"]["metadata"]["time"]["shape"][0] = n_times
        else:
            meta["shape"][0] = n_times
        p.write_text(json.dumps(meta))
    for name in ("mag", "observable"):
        chunk_dir = dst / name / "c"
        have = sorted(int(d.name) for d in chunk_dir.iterdir())
        tc = json.loads((dst / name / "zarr.json").read_text())["chunk_grid"]["configuration"]["chunk_shape"][
            0
        ]
        for k in range(len(have), -(-n_times // tc)):
            shutil.copytree(chunk_dir / str(have[k % len(have)]), chunk_dir / str(k))


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, required=True, help="a finished campaign's results folder")
    ap.add_argument("--steps", default="0.01,0.02,0.05,0.069", help="quantisation steps to chart, mag")
    ap.add_argument("--step", type=float, default=0.02, help="the step whose reads are timed (default 0.02)")
    ap.add_argument("--threads", type=int, default=2, help="the writer's threads (the rule's: 2)")
    ap.add_argument("--batch", type=int, default=1_000_000, help="random samples per SkyMaps batch")
    ap.add_argument("--xarray-batch", type=int, default=20_000)
    ap.add_argument("--skymodel-batch", type=int, default=20_000)
    ap.add_argument("--campaign-wall-s", type=float, default=None, help="the campaign's wall seconds")
    ap.add_argument("--no-skymodel", action="store_true")
    ap.add_argument(
        "--skymodel-catalog", action="store_true", help="SkyModel with the campaign's star table (slower)"
    )
    args = ap.parse_args(argv)

    import xarray as xr

    import straylight
    from straylight.cube.compact import write_compact

    bg_path = args.results / "background.zarr"
    bg = xr.open_zarr(bg_path)
    nt, npix, nb = bg.sizes["time"], bg.sizes["pixel"], bg.sizes["band"]
    nside = int(bg.attrs["healpix_nside"])
    out = {
        "results": str(args.results),
        "times": nt,
        "pixels": npix,
        "nside": nside,
        "bands": nb,
        "samples": nt * npix,
        "observable_fraction": float(bg["observable"].mean().compute()),
        "load_before": os.getloadavg(),
        "cpu_count": os.cpu_count(),
        "steps": {},
    }
    print(
        f"{args.results}: {nt} times x {npix} pixels (nside {nside}) x {nb} bands; load {out['load_before']}"
    )
    tmp = Path(tempfile.mkdtemp(prefix="compact_bench_"))
    try:
        steps = sorted({float(s) for s in args.steps.split(",")} | {args.step})
        for step in steps:
            dst = tmp / f"step_{step:g}.zarr"
            info, wall, cpu = timed(
                lambda dst=dst, step=step: write_compact(bg_path, dst, step, threads=args.threads)
            )
            rec = {
                "bytes": info["bytes"],
                "bytes_per_sample": info["bytes_per_sample"],
                "write_wall_s": wall,
                "write_cpu_s": cpu,
                "write_samples_per_s": info["samples"] / wall,
                **{k: dict(zip(info["bands"], info[k], strict=True)) for k in info if k.startswith("error_")},
            }
            out["steps"][f"{step:g}"] = rec
            print(
                f"step {step:g} mag: {rec['bytes_per_sample']:.4f} bytes/sample; rms "
                f"{max(info['error_rms_mag']):.4f}, p99.9 {max(info['error_p999_mag']):.4f}, max "
                f"{max(info['error_max_mag']):.4f} mag (worst band); write {wall:.1f} s wall, {cpu:.1f} s CPU"
            )
        main_store = tmp / f"step_{args.step:g}.zarr"
        if args.campaign_wall_s:
            w = out["steps"][f"{args.step:g}"]["write_wall_s"]
            out["campaign_wall_s"] = args.campaign_wall_s
            out["write_share_of_campaign_wall"] = w / args.campaign_wall_s
            print(
                f"write {w:.1f} s = {100 * w / args.campaign_wall_s:.1f} % of the campaign's "
                f"{args.campaign_wall_s} s"
            )

        rng = np.random.default_rng(1)
        sky, t_open, _ = timed(lambda: straylight.SkyMaps(main_store))
        times = sky.times
        cadence = times[1] - times[0]

        def random_times(n):
            i = rng.integers(0, nt - 1, n)
            return times[i] + (rng.random(n) * cadence.astype(np.int64)).astype("timedelta64[ns]")

        _, t_first, _ = timed(lambda: sky.map(random_times(1)[0]))
        _, t_load, c_load = timed(sky.load)
        map_ms, map_cpu_ms = [], []
        for t in random_times(200):
            _, w, c = timed(lambda t=t: sky.map(t))
            map_ms.append(1e3 * w)
            map_cpu_ms.append(1e3 * c)
        it_pix = sky.pixels[rng.integers(0, npix, args.batch)]
        bt = random_times(args.batch)
        sky.values(bt[:10], it_pix[:10])  # the compiled gather loaded
        batch_s, batch_cpu_s = [], []
        for _ in range(5):
            _, w, c = timed(lambda: sky.values(bt, it_pix))
            batch_s.append(w)
            batch_cpu_s.append(c)
        out["skymaps"] = {
            "open_s": t_open,
            "first_map_s": t_first,
            "decode_all_s": t_load,
            "decode_all_cpu_s": c_load,
            "map_ms_median": float(np.median(map_ms)),
            "map_ms_p90": float(np.percentile(map_ms, 90)),
            "map_cpu_ms_median": float(np.median(map_cpu_ms)),
            "map_values_per_s": 12 * nside**2 * nb / (np.median(map_ms) / 1e3),
            "batch_samples": args.batch,
            "batch_s_median": float(np.median(batch_s)),
            "batch_values_per_s": args.batch * nb / float(np.median(batch_s)),
            "batch_cpu_s_median": float(np.median(batch_cpu_s)),
            "batch_values_per_cpu_s": args.batch * nb / float(np.median(batch_cpu_s)),
        }
        print(
            "SkyMaps: open {open_s:.3f} s; first map {first_map_s:.3f} s; decode all {decode_all_s:.2f} s; "
            "map {map_ms_median:.2f} ms (p90 {map_ms_p90:.2f}; CPU {map_cpu_ms_median:.2f}); batch "
            "{batch_samples} samples in {batch_s_median:.3f} s = {batch_values_per_s:.3g} values/s (CPU "
            "{batch_cpu_s_median:.3f} s = {batch_values_per_cpu_s:.3g} values/CPU-s)".format(**out["skymaps"])
        )
        year = tmp / "year.zarr"
        n_year = int(round(365.25 * 86400 / (cadence / np.timedelta64(1, "s"))))
        year_store(main_store, year, n_year)
        opens = []
        for _ in range(5):
            y, w, _ = timed(lambda: straylight.SkyMaps(year))
            opens.append(w)
        y.map(times[-1])
        out["year_open_s"] = float(np.median(opens))
        out["year_times"] = n_year
        print(f"a year's product ({n_year} times): opened in {out['year_open_s']:.3f} s (median of 5)")

        # xarray on background.zarr
        zp = bg["mag_zero_point"]

        def xr_map():
            tot = bg["total"].isel(time=int(rng.integers(0, nt))).values
            return zp.values[None, :] - 2.5 * np.log10(tot)

        xr_map()
        xm = [timed(xr_map) for _ in range(10)]
        ii = xr.DataArray(rng.integers(0, nt, args.xarray_batch), dims="s")
        pp = xr.DataArray(rng.integers(0, npix, args.xarray_batch), dims="s")
        _, xb, xb_cpu = timed(lambda: bg["total"].isel(time=ii, pixel=pp).values)
        out["xarray"] = {
            "map_ms_median": 1e3 * float(np.median([x[1] for x in xm])),
            "map_cpu_ms_median": 1e3 * float(np.median([x[2] for x in xm])),
            "batch_cpu_s": xb_cpu,
            "batch_samples": args.xarray_batch,
            "batch_s": xb,
            "batch_values_per_s": args.xarray_batch * nb / xb,
        }
        print(
            "xarray on background.zarr: map {map_ms_median:.1f} ms; batch {batch_samples} samples in "
            "{batch_s:.2f} s = {batch_values_per_s:.3g} values/s".format(**out["xarray"])
        )
        if not args.no_skymodel:
            import astropy.units as u
            from astropy.coordinates import SkyCoord
            from astropy.time import Time

            from straylight.util.healpix import healpy

            hp = healpy()
            nest = bg.attrs.get("healpix_ordering", "ring") == "nested"
            catalog = args.results / "stars_csst.parquet" if args.skymodel_catalog else None
            model, t_build, _ = timed(lambda: straylight.SkyModel(catalog=catalog))
            ra, dec = hp.pix2ang(nside, bg["pixel"].values, nest=nest, lonlat=True)
            coords = SkyCoord(ra * u.deg, dec * u.deg)
            t0 = Time(times[nt // 2])
            model.background(t0, coords[:10])
            _, sm_map, sm_map_cpu = timed(lambda: model.background(t0, coords))
            sel = rng.integers(0, npix, args.skymodel_batch)
            tb = Time(random_times(args.skymodel_batch))
            _, sm_b, sm_b_cpu = timed(lambda: model.background(tb, coords[sel]))
            out["skymodel"] = {
                "build_s": t_build,
                "catalog": bool(catalog),
                "map_s": sm_map,
                "map_cpu_s": sm_map_cpu,
                "batch_samples": args.skymodel_batch,
                "batch_s": sm_b,
                "batch_cpu_s": sm_b_cpu,
                "batch_values_per_s": args.skymodel_batch * nb / sm_b,
            }
            print(
                "SkyModel: built {build_s:.1f} s; footprint map at one time {map_s:.2f} s; batch "
                "{batch_samples} samples in {batch_s:.2f} s = {batch_values_per_s:.3g} values/s".format(
                    **out["skymodel"]
                )
            )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    out["load_after"] = os.getloadavg()
    write_results(f"compact_{args.results.name}", out)
    return out


if __name__ == "__main__":
    main()
