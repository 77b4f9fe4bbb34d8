"""Benchmark: the products on disk: bytes per (time, pixel) sample per store, the
stored values' error against a reference run of the same campaign, and the two read patterns.

    python bench/storage.py --run compressed=results/default --run lossless=/tmp/ref/results/default \\
        --reference lossless --uncompressed /tmp/uncompressed

Each ``--run label=DIR`` is a campaign's results directory (background.zarr, limits.zarr,
observability.zarr, ephemeris.zarr).  ``--reference LABEL``: the run the others' values are
compared with, variable by variable over the whole cube (max |stored - reference| / |reference|
over its finite nonzero values; zeros, NaN and inf must be stored as they are).
``--uncompressed DIR``: also write the reference's products with no compression at all (same
chunks) to DIR and time the reads there.  Read patterns, best and median of ``--repeat`` (each
opens the store, consolidated metadata, and loads every (time, pixel) data variable): one
pointing over the whole campaign (all times at the footprint's middle pixel) and the whole sky at
one time (every pixel at the middle time).  The files are in the page cache after the first
read: the figures are decode and Zarr costs, not the disk's.  Writing: the reference's first
time block of background.zarr (every pixel) written again through the products' codecs
(``--config``'s storage section), through xarray's default ones and with none, best of
``--repeat``: what the codecs add to a time-block job.  Writes bench/results/storage.json.

The cube's chunk I/O per region (``--regions DIR``, DIR a campaign's results directory, e.g. a
month at nside 32 from bench/pipeline.py or the pipeline): some (time block, pixel block)
regions' values of every (time, pixel) array of background.zarr, limits.zarr and
observability.zarr (what a cube worker writes per region) written into empty copies of the
stores (metadata only) through straylight.storage.zarr_io.ChunkWriter and through zarr's public
``array[region] = values``, interleaved, the two copies' files compared byte for byte; and the
chunk reads of the steps after the cube (the limits' per-pixel summaries: limiting_mag and
observable over every time, one pixel block at a time; the time series: every band variable and
observable over every time at one pixel) through straylight.storage.zarr_io.read_region and
through zarr's ``array[region]``.  CPU and wall ms, best and median of ``--repeat``; writes
bench/results/storage_regions.json.

    python bench/storage.py --regions /tmp/month32/results/month32
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402

PRODUCTS = ("background.zarr", "limits.zarr", "observability.zarr", "ephemeris.zarr")
#: the (time, pixel) products: the ones the read patterns and the error comparison cover
GRIDDED = PRODUCTS[:3]


def _bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def _gridded_vars(ds) -> list:
    return [n for n, v in ds.data_vars.items() if v.dims[:2] == ("time", "pixel")]


def _open(path: Path):
    import xarray as xr

    return xr.open_zarr(path, consolidated=True)


def _time_reads(path: Path, repeat: int) -> dict:
    """ms to read one pointing over the campaign and the whole sky at one time."""
    with _open(path) as ds:
        names = _gridded_vars(ds)
        it, ip = ds.sizes["time"] // 2, ds.sizes["pixel"] // 2
    out = {}
    for pattern, sel in (("pointing_all_times_ms", {"pixel": ip}), ("sky_one_time_ms", {"time": it})):
        runs = []
        for _ in range(repeat + 1):  # the first: page cache and imports
            t0 = time.perf_counter()
            with _open(path) as ds:
                ds[names].isel(sel).load()
            runs.append(1e3 * (time.perf_counter() - t0))
        out[pattern] = {"best": min(runs[1:]), "median": float(np.median(runs[1:]))}
    return out


def _max_relative_error(stored: np.ndarray, reference: np.ndarray) -> float:
    s, r = np.asarray(stored, dtype=float), np.asarray(reference, dtype=float)
    exact = (r == 0) | ~np.isfinite(r)
    if not np.array_equal(s[exact], r[exact], equal_nan=True):
        return float("inf")
    return float(np.max(np.abs(s[~exact] - r[~exact]) / np.abs(r[~exact]), initial=0.0))


def _errors(path: Path, reference: Path) -> dict:
    """Per data variable: max relative error against the reference and the recorded bound."""
    out = {}
    with _open(path) as ds, _open(reference) as ref:
        for name in ds.data_vars:
            s, r = ds[name], ref[name]
            if s.dtype.kind != "f":
                out[name] = {
                    "max_relative_error": 0.0 if np.array_equal(s.values, r.values) else float("inf"),
                    "bound": s.attrs.get("max_relative_error"),
                }
                continue
            # block by block over time: the whole cube never in memory twice
            step = max(1, int(s.chunks[0][0])) if s.chunks and "time" in s.dims else None
            if step is None:
                err = _max_relative_error(s.values, r.values)
            else:
                err = max(
                    _max_relative_error(
                        s.isel(time=slice(t, t + step)).values, r.isel(time=slice(t, t + step)).values
                    )
                    for t in range(0, s.sizes["time"], step)
                )
            out[name] = {"max_relative_error": err, "bound": s.attrs.get("max_relative_error")}
    return out


def _write_uncompressed(reference_dir: Path, out_dir: Path) -> None:
    """The reference's gridded products again with no compressor and no filter (same chunks)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for product in GRIDDED:
        target = out_dir / product
        shutil.rmtree(target, ignore_errors=True)
        with _open(reference_dir / product) as ds:
            enc = {n: {"compressors": None, "filters": None} for n in ds.data_vars}
            for n in ds.variables:
                ds[n].encoding = {k: v for k, v in ds[n].encoding.items() if k in ("chunks",)}
            ds.to_zarr(target, mode="w", consolidated=True, encoding=enc)


def _time_writes(reference_dir: Path, storage: dict, repeat: int, tmp: Path) -> dict:
    """ms and us per sample to write the reference's first background time block three ways."""
    from straylight.storage.zarr_io import encoded

    with _open(reference_dir / "background.zarr") as bg:
        step = int(bg["total"].chunks[0][0])
        block = bg[_gridded_vars(bg)].isel(time=slice(0, step)).load()
        chunks = {n: {"chunks": tuple(c[0] for c in bg[n].chunks)} for n in block.data_vars}
    for n in block.variables:
        block[n].encoding = {}
    samples = block.sizes["time"] * block.sizes["pixel"]
    compressed, enc = encoded(block, storage)
    ways = {
        "products_codecs": (compressed, {n: {**enc[n], **chunks[n]} for n in enc}),
        "xarray_default": (block, chunks),
        "none": (block, {n: {**chunks[n], "compressors": None} for n in chunks}),
    }
    out = {"samples": samples}
    for label, (ds, encoding) in ways.items():
        runs = []
        for _ in range(repeat):
            shutil.rmtree(tmp, ignore_errors=True)
            t0 = time.perf_counter()
            ds.to_zarr(tmp, mode="w", consolidated=False, encoding=encoding)
            runs.append(time.perf_counter() - t0)
        out[label] = {
            "best_ms": 1e3 * min(runs),
            "us_per_sample": 1e6 * min(runs) / samples,
            "bytes": _bytes(tmp),
        }
    shutil.rmtree(tmp, ignore_errors=True)
    return out


def _region_arrays(results_dir: Path) -> dict:
    """store -> names of its (time, pixel[, band]) arrays: those a cube worker writes per region."""
    import zarr

    out = {}
    for product in GRIDDED:
        group = zarr.open_group(str(results_dir / product), mode="r", use_consolidated=False)
        out[product] = sorted(
            n for n, a in group.arrays() if tuple(a.metadata.dimension_names or ())[:2] == ("time", "pixel")
        )
    return out


def _region_list(shape: tuple, chunks: tuple, n_time_blocks: int) -> list:
    """Every pixel block of ``n_time_blocks`` time blocks spread over the campaign: chunk-aligned
    (time, pixel) regions, as the cube's workers write them."""
    nt = -(-shape[0] // chunks[0])
    blocks = sorted({int(round(k * (nt - 1) / max(n_time_blocks - 1, 1))) for k in range(n_time_blocks)})
    return [
        (slice(t * chunks[0], min((t + 1) * chunks[0], shape[0])), slice(p, min(p + chunks[1], shape[1])))
        for t in blocks
        for p in range(0, shape[1], chunks[1])
    ]


def _cpu_wall(fn) -> tuple:
    """(CPU s of this process, every thread; wall s) of ``fn()``."""
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def _summary(runs: list, per: int) -> dict:
    cpu, wall = np.array([r[0] for r in runs]) * 1e3 / per, np.array([r[1] for r in runs]) * 1e3 / per
    return {
        "cpu_ms": {"best": float(cpu.min()), "median": float(np.median(cpu))},
        "wall_ms": {"best": float(wall.min()), "median": float(np.median(wall))},
    }


def _time_regions(results_dir: Path, repeat: int, n_time_blocks: int, tmp: Path) -> dict:
    """Per region: CPU and wall ms to write its chunks through ChunkWriter and through zarr's
    public API; per read pattern: through read_region and through zarr."""
    import zarr

    from straylight.storage.zarr_io import ChunkWriter, read_region

    arrays = _region_arrays(results_dir)
    src = {p: zarr.open_group(str(results_dir / p), mode="r", use_consolidated=False) for p in arrays}
    total = src["background.zarr"]["total"]
    regions = _region_list(total.shape, total.chunks, n_time_blocks)
    values = {(p, n): [np.asarray(src[p][n][r]) for r in regions] for p in arrays for n in arrays[p]}

    def empty_copy(label):
        for p in arrays:  # metadata only: no chunk folder
            target = tmp / label / p
            shutil.rmtree(target, ignore_errors=True)
            shutil.copytree(results_dir / p, target, ignore=lambda d, names: [n for n in names if n == "c"])

    def opened(label, writer):
        out = {}
        for p in arrays:
            group = zarr.open_group(str(tmp / label / p), mode="r+", use_consolidated=False)
            out.update({(p, n): ChunkWriter(group[n]) if writer else group[n] for n in arrays[p]})
        return out

    def write(targets):
        for i, r in enumerate(regions):
            for key, target in targets.items():
                target[r] = values[key][i]

    ways = {"chunk_writer": True, "zarr_public": False}
    runs = {w: [] for w in ways}
    for _ in range(repeat):
        for way, writer in ways.items():  # interleaved: the machine's load shared alike
            empty_copy(way)
            targets = opened(way, writer)
            runs[way].append(_cpu_wall(lambda: write(targets)))
    files = {
        w: {str(f.relative_to(tmp / w)): f.read_bytes() for f in sorted((tmp / w).rglob("*")) if f.is_file()}
        for w in ways
    }
    out = {
        "regions": len(regions),
        "chunks_per_region": len(values),
        "region_shape": [int(total.chunks[0]), int(total.chunks[1])],
        "files_identical": files["chunk_writer"] == files["zarr_public"],
        "write_per_region": {w: _summary(runs[w], len(regions)) for w in ways},
    }

    # the reads after the cube: limits' summaries by pixel block, the time series at one pixel
    limits = zarr.open_group(str(results_dir / "limits.zarr"), mode="r", use_consolidated=False)
    background = src["background.zarr"]
    block = int(limits["observable"].chunks[1])
    series = [n for n in arrays["background.zarr"] if background[n].ndim == 3] + ["observable"]
    middle = total.shape[1] // 2
    patterns = {
        "limits_pixel_block_all_times": (
            [limits["limiting_mag"], limits["observable"]],
            (slice(None), slice(0, block)),
        ),
        "series_one_pixel_all_times": (
            [background[n] for n in series],
            (slice(None), slice(middle, middle + 1)),
        ),
    }
    readers = {"read_region": read_region, "zarr_public": lambda a, r: np.asarray(a[r])}
    out["reads"] = {}
    for pattern, (targets, region) in patterns.items():
        runs = {w: [] for w in readers}
        for _ in range(repeat):
            for way, read in readers.items():
                runs[way].append(_cpu_wall(lambda: [read(a, region) for a in targets]))
        same = all(
            np.array_equal(read_region(a, region), np.asarray(a[region]), equal_nan=True) for a in targets
        )
        chunks = len(targets) * -(-total.shape[0] // int(total.chunks[0]))
        out["reads"][pattern] = {
            "arrays": len(targets),
            "chunks": chunks,
            "same_values": bool(same),
            **{w: _summary(runs[w], 1) for w in readers},
        }
    shutil.rmtree(tmp, ignore_errors=True)
    return out


def _print_regions(r: dict) -> None:
    w = r["write_per_region"]
    print(
        f"writing {r['regions']} regions of {r['region_shape'][0]} times x {r['region_shape'][1]} pixels, "
        f"{r['chunks_per_region']} chunks each (files identical: {r['files_identical']}):"
    )
    for way, s in w.items():
        print(
            f"  {way}: {s['cpu_ms']['best']:.1f} CPU-ms a region (median {s['cpu_ms']['median']:.1f}), "
            f"wall {s['wall_ms']['best']:.1f} ms (median {s['wall_ms']['median']:.1f})"
        )
    for pattern, s in r["reads"].items():
        ways = ", ".join(
            f"{way} {s[way]['cpu_ms']['best']:.0f} CPU-ms "
            f"(median {s[way]['cpu_ms']['median']:.0f}), wall {s[way]['wall_ms']['best']:.0f} ms"
            for way in ("read_region", "zarr_public")
        )
        print(
            f"reading {pattern} ({s['arrays']} arrays, {s['chunks']} chunks; "
            f"same values: {s['same_values']}): {ways}"
        )


def main(argv=None) -> dict:
    warnings.filterwarnings("ignore", message="Numcodecs codecs are not in the Zarr version 3")
    warnings.filterwarnings("ignore", message="Consolidated metadata is currently not part")
    warnings.filterwarnings("ignore", message="Object at .snakemake_timestamp is not recognized")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", action="append", metavar="LABEL=DIR")
    ap.add_argument(
        "--regions",
        type=Path,
        metavar="DIR",
        help="a campaign's results directory: time the cube's chunk writes and reads per region",
    )
    ap.add_argument(
        "--region-time-blocks",
        type=int,
        default=3,
        help="time blocks (every pixel block of each) written by --regions",
    )
    ap.add_argument("--reference", help="label of the run the others are compared with")
    ap.add_argument(
        "--uncompressed", type=Path, help="write the reference's products uncompressed here, and time them"
    )
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument(
        "--config",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "config" / "config.yaml",
        help="campaign config whose storage section the write timing uses",
    )
    args = ap.parse_args(argv)
    if args.regions is not None:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            r = _time_regions(args.regions, args.repeat, args.region_time_blocks, Path(tmp))
        results = {
            "machine": {
                "platform": platform.platform(),
                "cpus": os.cpu_count(),
                "load_average_at_start": list(os.getloadavg()),
            },
            "results_dir": str(args.regions),
            **r,
        }
        _print_regions(results)
        write_results("storage_regions", results)
        if not args.run:
            return results
    if not args.run:
        ap.error("--run or --regions is needed")
    runs = dict(r.split("=", 1) for r in args.run)
    runs = {k: Path(v) for k, v in runs.items()}
    if args.uncompressed is not None:
        if args.reference is None:
            ap.error("--uncompressed needs --reference")
        _write_uncompressed(runs[args.reference], args.uncompressed)
        runs["uncompressed"] = args.uncompressed
    results = {
        "machine": {
            "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "load_average_at_start": list(os.getloadavg()),
        },
        "note": "read times: page-cached files, best and median of repeated open + load",
        "runs": {},
    }
    for label, d in runs.items():
        with _open(d / "background.zarr") as bg:
            samples = bg.sizes["time"] * bg.sizes["pixel"]
        stores = {}
        for product in PRODUCTS:
            if not (d / product).exists():
                continue
            b = _bytes(d / product)
            stores[product] = {"bytes": b, "bytes_per_sample": b / samples}
        run = {
            "dir": str(d),
            "samples": samples,
            "stores": stores,
            "bytes_per_sample_gridded_products": sum(
                stores[p]["bytes_per_sample"] for p in GRIDDED if p in stores
            ),
            "bytes_per_sample_all": sum(s["bytes_per_sample"] for s in stores.values()),
            "reads": {p: _time_reads(d / p, args.repeat) for p in GRIDDED if p in stores},
        }
        if args.reference and label != args.reference and label != "uncompressed":
            run["errors_against_" + args.reference] = {
                p: _errors(d / p, runs[args.reference] / p) for p in GRIDDED if p in stores
            }
        results["runs"][label] = run
        print(
            f"{label}: {run['bytes_per_sample_gridded_products']:.2f} bytes/sample "
            "(background+limits+observability), "
            + ", ".join(f"{p} {s['bytes_per_sample']:.2f}" for p, s in stores.items())
        )
        for p, r in run["reads"].items():
            print(
                f"  {p}: one pointing, all times {r['pointing_all_times_ms']['best']:.1f} ms; "
                f"whole sky, one time {r['sky_one_time_ms']['best']:.1f} ms (best of {args.repeat})"
            )
        for p, errs in run.get("errors_against_" + str(args.reference), {}).items():
            worst = max(errs.items(), key=lambda kv: kv[1]["max_relative_error"])
            print(
                f"  {p}: max relative error {worst[1]['max_relative_error']:.3g} "
                f"({worst[0]}, bound {worst[1]['bound']})"
            )
    if args.reference:
        from straylight.config import load_campaign

        storage = load_campaign(args.config).config["storage"]
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            w = _time_writes(runs[args.reference], storage, args.repeat, Path(tmp) / "block.zarr")
        results["write_one_time_block"] = {"storage": storage, **w}
        print(
            f"writing one time block ({w['samples']} samples): "
            + ", ".join(
                f"{k} {v['best_ms']:.0f} ms ({v['us_per_sample']:.2f} us/sample)"
                for k, v in w.items()
                if k != "samples"
            )
        )
    write_results("storage", results)
    return results


if __name__ == "__main__":
    main()
