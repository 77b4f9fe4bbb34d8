"""Snakemake adapter: rule `sky_compact` -> sky_compact.zarr (straylight.cube.compact)."""

import sys
from pathlib import Path


def main(snakemake):
    sys.path.insert(0, str(Path(snakemake.scriptdir)))
    from _common import campaign, setup_logging

    from straylight.cube.compact import write_compact

    log = setup_logging(snakemake)
    settings = campaign(snakemake).settings.storage
    info = write_compact(
        snakemake.params.store,
        snakemake.output[0],
        settings.compact_mag_step,
        threads=snakemake.threads,
    )
    log.info(
        "wrote %s: %.3f bytes/sample (%d samples, %d observable), step %g mag",
        snakemake.output[0],
        info["bytes_per_sample"],
        info["samples"],
        info["observable_samples"],
        settings.compact_mag_step,
    )
    for i, b in enumerate(info["bands"]):
        log.info(
            "band %-4s: error rms %.4f, p99.9 %.4f, max %.4f mag",
            b,
            info["error_rms_mag"][i],
            info["error_p999_mag"][i],
            info["error_max_mag"][i],
        )


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 - injected by Snakemake
    from _common import end_job

    end_job()
