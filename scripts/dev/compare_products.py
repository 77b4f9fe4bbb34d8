"""Compare two runs' products: per band the footprint's median depth (limiting_mag_median's
10/50/90th percentiles over observable pixels, mag AB), the observable fraction, and the
scheduling tables (largest change per column).  Prints Markdown.

    python scripts/dev/compare_products.py BEFORE_RESULTS_DIR AFTER_RESULTS_DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr


def depth_rows(results: Path) -> dict:
    ds = xr.open_zarr(results / "limits.zarr")
    frac = ds["observable_fraction"].values
    seen = frac > 0
    out = {"observable_fraction": float(ds["observable"].values.mean())}
    for name in ("limiting_mag_median", "limiting_mag_median_pessimistic", "limiting_mag_median_optimistic"):
        if name not in ds:
            continue
        values = ds[name].values[seen]
        for j, band in enumerate(ds["band"].values):
            v = values[:, j]
            v = v[np.isfinite(v)]
            out[(name, str(band))] = np.percentile(v, [10, 50, 90]) if v.size else [np.nan] * 3
    return out


def main(before: str, after: str) -> None:
    b, a = Path(before), Path(after)
    rb, ra = depth_rows(b), depth_rows(a)
    print(
        f"observable fraction of (time, pixel) samples: {rb['observable_fraction']:.4f} -> "
        f"{ra['observable_fraction']:.4f}\n"
    )
    print("| band | median depth p10/p50/p90 before | after | change of p50 (mag) |")
    print("|---|---|---|---|")
    for key in rb:
        if isinstance(key, tuple) and key[0] == "limiting_mag_median":
            x, y = rb[key], ra.get(key, [np.nan] * 3)
            print(
                f"| {key[1]} | {x[0]:.2f} / {x[1]:.2f} / {x[2]:.2f} | {y[0]:.2f} / {y[1]:.2f} / "
                f"{y[2]:.2f} | {y[1] - x[1]:+.3f} |"
            )
    for key in ra:
        if isinstance(key, tuple) and key[0] != "limiting_mag_median" and key[1] == "g":
            y = ra[key]
            print(f"\nafter, {key[0]} (g): p10/p50/p90 {y[0]:.2f} / {y[1]:.2f} / {y[2]:.2f}")
    mb = xr.open_zarr(b / "limits.zarr")["limiting_mag_median"]
    ma = xr.open_zarr(a / "limits.zarr")["limiting_mag_median"]
    if mb.sizes == ma.sizes:
        d = (ma - mb).values
        print("\n| band | pixels whose median depth moves > 0.1 mag | largest move (mag) |")
        print("|---|---|---|")
        for j, band in enumerate(mb["band"].values):
            dj = d[:, j][np.isfinite(d[:, j])]
            big = int(np.sum(np.abs(dj) > 0.1))
            worst = dj[np.argmax(np.abs(dj))] if dj.size else np.nan
            print(f"| {band} | {big} of {dj.size} | {worst:+.3f} |")
    print("\n| scheduling table | column | largest change |")
    print("|---|---|---|")
    for csv in sorted((b / "scheduling").glob("*.csv")):
        other = a / "scheduling" / csv.name
        if not other.exists():
            print(f"| {csv.name} | (missing after) | |")
            continue
        x, y = pd.read_csv(csv), pd.read_csv(other)
        for col in x.columns[1:]:
            if col not in y:
                continue
            xv, yv = x[col].to_numpy(float), y[col].to_numpy(float)
            n = min(len(xv), len(yv))
            both = np.isfinite(xv[:n]) & np.isfinite(yv[:n])
            changed_finiteness = int(np.sum(np.isfinite(xv[:n]) != np.isfinite(yv[:n])))
            biggest = np.max(np.abs(yv[:n][both] - xv[:n][both])) if both.any() else 0.0
            if biggest > 0 or changed_finiteness:
                print(
                    f"| {csv.name} | {col} | {biggest:.3g}"
                    + (f"; {changed_finiteness} rows inf<->finite" if changed_finiteness else "")
                    + " |"
                )


if __name__ == "__main__":
    main(*sys.argv[1:3])
