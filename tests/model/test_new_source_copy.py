"""Issue #54's check on the registry: in a temporary copy of the package and its config, a new
source (a constant glow read from one new setting) is added by exactly three edits: its own
module, its registry entry (a factory, a component and a source entry in
straylight/model/registry.py) and its schema entry (config/schema/config.schema.yaml, with a
default).  Nothing else changes, and the copy's API table and cube region carry the new
component, add it into the total, and read its value from the setting."""

from __future__ import annotations

import filecmp
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

#: the glow's e-/s/pix in every band, the new setting's default (a round number, so the totals
#: move by exactly it)
GLOW_E_PER_S = 0.25

GLOW_MODULE = '''"""A constant glow: the same e-/s/pix in every band, from models.glow_e_per_s_per_pix."""

import numpy as np

from straylight.sources.rates import BandRates


class ConstantGlow:
    """models.glow_e_per_s_per_pix e-/s/pix in every band, everywhere."""

    def __init__(self, context):
        self.e_per_s_per_pix = float(context.campaign.settings.models.glow_e_per_s_per_pix)

    def rates(self, samples, bands) -> BandRates:
        n = int(np.prod(samples.shape))
        return BandRates(per_band={"glow": np.full((len(bands), n), self.e_per_s_per_pix)})
'''

SCHEMA_ENTRY = f"""      glow_e_per_s_per_pix:
        type: number
        minimum: 0
        default: {GLOW_E_PER_S}
        description: "A constant glow in every band, e-/s/pix."
"""

REGISTRY_FACTORY = """def _glow(model):
    from straylight.sources.glow import ConstantGlow

    return ConstantGlow(model.context)


"""

#: in the copy: the API at two samples and a cube region, each with the glow and its total, and
#: the cube store's declaration of the glow
PROBE = """
import json
import astropy.units as u
from astropy.coordinates import SkyCoord
from astropy.time import Time
from straylight.config import load_campaign
from straylight.cube.footprint import footprint_from_config
from straylight.cube.region import compute_region
from straylight.cube.store import empty_cube
from straylight.model import BackgroundModel
from straylight.skymodel import SkyModel

direct = {"models": {"earthshine": {"method": "direct"}}}
t = Time(["2026-01-01T03:00:00", "2026-01-01T09:00:00"])
coord = SkyCoord([10.0, 200.0] * u.deg, [-30.0, 45.0] * u.deg)
table = SkyModel(config=direct).background(t, coord, bands=["g"])
campaign = load_campaign(direct)
fp = footprint_from_config(campaign.settings.footprint)
model = BackgroundModel(campaign)
region = compute_region(campaign, fp, slice(0, 2), slice(0, 4), model=model)
out = {"total_g": table["total_g"].value.tolist(), "region_total": region["total"].values.tolist()}
if "glow_g" in table.colnames:
    out.update(
        glow_g=table["glow_g"].value.tolist(),
        unit=str(table["glow_g"].unit),
        description=table["glow_g"].info.description,
        region_glow=region["glow"].values.tolist(),
        long_name=empty_cube(campaign, fp, campaign.times[:2], model)["glow"].attrs["long_name"],
    )
print(json.dumps(out))
"""


def _insert_before(text: str, anchor: str, new: str, start: int = 0) -> str:
    i = text.index(anchor, start)
    return text[:i] + new + text[i:]


def _add_glow(copy: Path) -> None:
    """The three edits: the module, the registry entry, the schema entry."""
    (copy / "straylight/sources/glow.py").write_text(GLOW_MODULE)
    registry = copy / "straylight/model/registry.py"
    text = registry.read_text()
    text = _insert_before(
        text,
        "\n]\n",
        '\n    Component("glow", "a constant glow in every band"),',
        text.index("COMPONENTS = ["),
    )
    text = _insert_before(text, "#: the sources of light", REGISTRY_FACTORY)
    entry = (
        '\n    SourceEntry("glow", "glow", _glow, skippable=True,'
        ' parameters=("models.glow_e_per_s_per_pix",)),'
    )
    text = _insert_before(text, "\n]\n", entry, text.index("SOURCES = ["))
    registry.write_text(text)
    schema = copy / "config/schema/config.schema.yaml"
    text = schema.read_text()
    models = text.index("\n  models:\n")
    schema.write_text(
        _insert_before(text, "\n", "\n" + SCHEMA_ENTRY.rstrip("\n"), text.index("    properties:", models))
    )


def _changed(copy: Path) -> set[str]:
    """Files of straylight/ and config/ that differ between the copy and the checkout."""
    out = set()
    for top in ("straylight", "config"):
        for path in (copy / top).rglob("*"):
            if path.is_file() and "__pycache__" not in path.parts:
                rel = path.relative_to(copy)
                if not (ROOT / rel).is_file() or not filecmp.cmp(path, ROOT / rel, shallow=False):
                    out.add(str(rel))
    return out


def _probe(where: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(where))
    r = subprocess.run(
        [sys.executable, "-c", PROBE], cwd=where, env=env, capture_output=True, text=True, timeout=900
    )
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_a_new_source_is_its_module_its_registry_entry_and_its_schema_entry(tmp_path):
    copy = tmp_path / "copy"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for top in ("straylight", "config"):
        shutil.copytree(ROOT / top, copy / top, ignore=ignore)
    before = _probe(copy)
    _add_glow(copy)
    assert _changed(copy) == {
        "straylight/sources/glow.py",
        "straylight/model/registry.py",
        "config/schema/config.schema.yaml",
    }
    after = _probe(copy)
    assert "glow_g" not in before
    np.testing.assert_array_equal(after["glow_g"], GLOW_E_PER_S)
    assert after["unit"] == "electron / (pix s)"
    assert after["description"].startswith("a constant glow")
    np.testing.assert_allclose(after["total_g"], np.add(before["total_g"], GLOW_E_PER_S), rtol=1e-14)
    np.testing.assert_array_equal(after["region_glow"], np.float32(GLOW_E_PER_S))
    assert after["long_name"] == "a constant glow in every band"
    # float32 totals: within a float32 rounding of the sum
    np.testing.assert_allclose(
        after["region_total"], np.add(before["region_total"], GLOW_E_PER_S), rtol=2e-7, atol=1e-6
    )
