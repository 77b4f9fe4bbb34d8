"""Digests of a campaign's products, to check that a change leaves them bit-identical.

Prints one line per product (and per array of a Zarr store): a SHA-256 of its decoded values,
shape, dtype and attributes.  Provenance (commit, dates, command) and the run's work/ folder
(logs, sentinels) are left out.

    python scripts/dev/product_digests.py results/default > before.txt
    ... change the code, run the campaign again ...
    python scripts/dev/product_digests.py results/default | diff before.txt -
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

#: files whose content records when and by what the run was made, not what it computed
SKIPPED = {"provenance.json", "plan.json"}


def _digest_array(values: np.ndarray, attrs: dict) -> str:
    h = hashlib.sha256()
    values = np.ascontiguousarray(values)
    h.update(f"{values.dtype.str}{values.shape}".encode())
    h.update(values.tobytes() if values.dtype != object else repr(values.tolist()).encode())
    h.update(json.dumps(attrs, sort_keys=True, default=str).encode())
    return h.hexdigest()[:16]


def zarr_digests(store: Path):
    import zarr

    group = zarr.open_group(str(store), mode="r")
    attrs = {k: v for k, v in group.attrs.asdict().items() if k != "provenance"}
    yield f"{store.name}/.attrs", _digest_array(np.zeros(0), attrs)
    for name, array in sorted(group.arrays()):
        yield f"{store.name}/{name}", _digest_array(array[...], array.attrs.asdict())


def fits_digests(path: Path):
    from astropy.io import fits

    with fits.open(path) as hdus:
        for i, hdu in enumerate(hdus):
            if hdu.data is None:
                continue
            data = hdu.data
            values = np.asarray(data.tolist() if hasattr(data, "columns") else data)
            yield f"{path.name}[{i}]", _digest_array(values, {})


def digests(root: Path):
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root)
        if (
            rel.parts[0] == "work"  # the run's working files: sentinels, work stores, logs
            or path.name.startswith(".")
            or path.name in SKIPPED
        ):
            continue
        if path.suffix == ".zarr" and path.is_dir():
            for name, d in zarr_digests(path):
                yield str(rel.parent / name), d
        elif ".zarr" in str(rel) or path.is_dir():
            continue
        elif path.suffix == ".fits":
            yield from ((str(rel.parent / n), d) for n, d in fits_digests(path))
        elif path.suffix == ".parquet":
            import pandas as pd

            frame = pd.read_parquet(path)
            yield str(rel), _digest_array(frame.to_numpy(), {"columns": list(frame.columns)})
        elif path.suffix in (".csv", ".json", ".rst"):
            yield str(rel), hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def main(argv=None) -> int:
    for root in argv or sys.argv[1:]:
        for name, d in digests(Path(root)):
            print(f"{d}  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
