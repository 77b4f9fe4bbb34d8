"""provenance.json: what produced a campaign's products and checksums of all of them."""
from __future__ import annotations

import hashlib
import platform
import sys
from importlib import metadata
from pathlib import Path

from straylight.util.io import sha256_path

PACKAGES = ("straylight", "numpy", "scipy", "astropy", "healpy", "xarray", "zarr", "dask", "distributed",
            "snakemake", "de405", "sgp4", "speclite", "erfa", "pyerfa")


def versions() -> dict:
    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            pass
    return out


def provenance_record(campaign, inputs: dict, outputs: dict) -> dict:
    data_dir = Path(__file__).resolve().parents[1] / "data"
    rec = {
        "campaign": campaign.name,
        "config": campaign.config,
        "config_file": str(campaign.path),
        "instrument_file": str(campaign.instrument_path),
        "versions": versions(),
        "inputs_sha256": {
            "config": sha256_path(campaign.path),
            "instrument": sha256_path(campaign.instrument_path),
            **{f"data/{f.name}": sha256_path(f) for f in sorted(data_dir.iterdir()) if f.is_file()},
            **{k: sha256_path(v) for k, v in inputs.items()},
        },
    }
    rec["outputs_sha256"] = {k: sha256_path(v) for k, v in outputs.items()}
    # one digest for the whole campaign: two runs from the same config and inputs must agree
    # (tests/survey/test_cube.py compares it after ten kill -9 and resumes)
    rec["outputs_digest_sha256"] = hashlib.sha256(
        "".join(f"{k}:{v}\n" for k, v in sorted(rec["outputs_sha256"].items())).encode()).hexdigest()
    return rec
