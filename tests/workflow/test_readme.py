"""Every code block of README.md and docs/commands.md runs, as a user on a fresh clone would run it.

Each block is preceded by a marker ``<!-- readme-test: ... -->`` saying how it runs: ``run``
(as is), ``run with a tiny campaign in place of config/config.yaml`` (the campaign block: a
one-hour campaign at nside 4 named ``default``, so that the blocks reading ``results/default``
read its products), ``run against a finished campaign's results``, or ``not run`` (one block
only: ``make run``/``make test``, which take minutes).  The blocks run in a copy of the
repository's tracked files, with this checkout's code.
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO

BLOCK = re.compile(r"<!-- readme-test: (?P<how>[^>]*?) -->\n```(?P<lang>\w+)\n(?P<code>.*?)```", re.S)
ANY_BLOCK = re.compile(r"^```\w*\n", re.M)


#: the pages whose blocks run: the README, and the commands' page it points to
PAGES = ("README.md", "docs/commands.md")


def blocks(page: str = "README.md"):
    text = (REPO / page).read_text()
    found = [(m["how"].strip(), m["lang"], m["code"]) for m in BLOCK.finditer(text)]
    return text, found


def all_blocks() -> list:
    return [b for page in PAGES for b in blocks(page)[1]]


@pytest.mark.parametrize("page", PAGES)
def test_every_block_is_marked_and_one_at_most_is_not_run(page):
    text, found = blocks(page)
    opening_fences = len(ANY_BLOCK.findall(text))
    assert len(found) * 2 == len(re.findall(r"^```", text, re.M)), "a code block without a readme-test marker"
    assert opening_fences >= len(found)
    not_run = [b for b in found if b[0].startswith("not run")]
    assert len(not_run) <= 1
    assert all(how.startswith(("run", "not run")) for how, _, _ in found)
    if page == "README.md":
        assert len(text.splitlines()) <= 300  # the project's before-stop check


def _env():
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def _run(lang, code, cwd, timeout=900):
    cmd = ["bash", "-euo", "pipefail", "-c", code] if lang == "bash" else [sys.executable, "-c", code]
    return subprocess.run(cmd, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def clone(tmp_path_factory):
    """The repository's tracked files (as a fresh clone has them), this checkout's content."""
    dst = tmp_path_factory.mktemp("clone")
    files = subprocess.run(
        ["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.split()
    for f in files:
        if (REPO / f).is_file():
            (dst / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / f, dst / f)
    return dst


@pytest.fixture(scope="module")
def campaign_run(clone):
    """The README's campaign block, with a tiny campaign named `default` in place of the default."""
    import yaml
    from conftest import tiny_config

    (clone / "tmp").mkdir(exist_ok=True)
    cfg = yaml.safe_load(tiny_config(clone / "tmp", name="default").read_text())
    cfg["campaign"].update(end="2026-01-01T01:00:00", cadence_s=1200, time_block_hours=1)
    cfg["instrument"] = "instruments/csst.yaml"  # as in config/config.yaml: relative to config/
    tiny = clone / "tmp" / "tiny_default.yaml"
    tiny.write_text(yaml.safe_dump(cfg))
    _, found = blocks()
    ((how, lang, code),) = [b for b in found if "tiny campaign" in b[0]]
    assert "cp config/config.yaml config/my_campaign.yaml" in code
    r = _run(lang, code.replace("cp config/config.yaml", f"cp {tiny}"), clone)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "samples" in r.stdout  # straylight plan's report
    return clone / "results" / "default"


@pytest.mark.slow
def test_campaign_blocks_and_product_blocks_run(campaign_run, clone):
    _, found = blocks()
    product_blocks = [b for b in found if "finished campaign" in b[0]]
    assert len(product_blocks) >= 2
    for how, lang, code in product_blocks:
        r = _run(lang, code, clone)
        assert r.returncode == 0, code + r.stderr[-3000:]
        assert "Traceback" not in r.stderr


def test_plain_blocks_run(tmp_path, clone):
    plain = [b for b in all_blocks() if b[0] == "run"]
    assert len(plain) >= 4
    work = clone / "work"
    work.mkdir(exist_ok=True)
    for how, lang, code in plain:
        r = _run(lang, code, work)
        assert r.returncode == 0, code + r.stderr[-3000:]
    assert (work / "vis.png").stat().st_size > 10_000 and (work / "vis_windows.csv").exists()


def test_slurm_block_dry_run(clone):
    """The cluster block as written: the plugin installed, the profile read, the cycle's jobs
    planned (-n); tests/workflow/test_slurm.py submits a campaign to a real SLURM."""
    _, found = blocks()
    ((how, lang, code),) = [b for b in found if b[0].startswith("run as a dry run")]
    assert "snakemake -n --profile workflow/profiles/slurm" in code
    r = _run(lang, code, clone)
    assert r.returncode == 0, code + r.stdout[-2000:] + r.stderr[-3000:]
    assert "background_blocks" in r.stdout + r.stderr


def readme_products() -> set:
    """The files and folders the README's products table names: every name of its first column
    (first path component), and the file names in its content column (``stars_gaia.parquet``)."""
    text = (REPO / "README.md").read_text().split("## What you get", 1)[1]
    table = next(chunk for chunk in text.split("\n\n") if chunk.startswith("| product"))
    rows = [ln.split("|") for ln in table.splitlines() if ln.startswith("| `")]
    names = {n.split("/")[0] for row in rows for n in re.findall(r"`([^`]+)`", row[1])}
    files = re.compile(r"[\w-]+\.(parquet|fits|json|zarr|csv|rst)")
    return names | {n for row in rows for n in re.findall(r"`([^`]+)`", row[2]) if files.fullmatch(n)}


@pytest.mark.slow
def test_every_entry_of_the_results_folder_is_in_the_products_table(campaign_run):
    """What a run leaves in results/<campaign>/ is a product the README lists, or in work/ (its
    logs, sentinels and summaries); `.fits` beside a listed `.parquet` counts as listed."""
    listed = readme_products()
    assert {"background.zarr", "maps", "work", "sky", "series"} <= listed
    stems = {Path(n).stem for n in listed}
    entries = sorted(p.name for p in campaign_run.iterdir())
    assert [e for e in entries if e not in listed and Path(e).stem not in stems] == []
    assert (campaign_run / "work" / "logs" / "snakemake.log").is_file()  # straylight run's quiet log


@pytest.mark.slow
def test_tiny_campaign_products_follow_the_conventions(campaign_run):
    """CF flags on the violation mask, zero points with the cube, units in Parquet, FITS keywords."""
    import numpy as np
    import pyarrow.parquet as pq
    import xarray as xr
    from astropy.io import fits

    from straylight.config import load_campaign
    from straylight.limits.point_source import sky_zero_points

    run = campaign_run
    bg = xr.open_zarr(run / "background.zarr")
    lim = xr.open_zarr(run / "limits.zarr")
    obs = xr.open_zarr(run / "observability.zarr")
    for v in (bg["violations"], obs["violations"]):
        assert list(v.attrs["flag_masks"]) == [1, 2, 4, 8, 16]
        assert v.attrs["flag_meanings"] == "sun moon bright_limb dark_limb earth_occultation"
    zp = sky_zero_points(load_campaign())
    for ds in (bg, lim):
        assert ds["mag_zero_point"].attrs["units"] == "mag(AB) arcsec-2"
        np.testing.assert_allclose(ds["mag_zero_point"].values, [zp[b] for b in ds["band"].values], atol=1e-9)
    assert pq.read_schema(run / "stars_csst.parquet").field("ra").metadata[b"unit"] == b"deg"
    h = fits.getheader(run / "maps" / "limit_best_g.fits", 1)
    assert (h["CAMPAIGN"], h["BAND"], h["DATE-BEG"], h["NTIMES"]) == (
        "default",
        "g",
        "2026-01-01T00:00:00",
        3,
    )
    assert h["DATE-END"] == "2026-01-01T01:00:00"  # campaign.end, not the last sample (00:40)
    assert h["EXPTIME"] == h["EXPONE"] * h["NEXP"]  # the total; the default: 2 x 150 s in g
    assert h["EXPONE"] == 150 and h["NEXP"] == 2
