"""Shared by the benchmark's parts: random observable samples of the default campaign with the
catalog's stars (:class:`Bench`), component models with chosen knobs, the default and reference
settings, a knob sweep against the reference, timing, and the Pareto chart."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _samples import random_samples

RESULTS = Path(__file__).resolve().parents[1] / "results"

#: runs of each fast cube timing (tens of ms each), the best kept
FAST_REPEATS = 7


def timed(fn, repeats=3):
    fn()  # warm-up: tables, caches
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def max_rel_error(res, ref, bands):
    return max(float(np.max(np.abs(res[b]["total"] - ref[b]["total"]) / ref[b]["total"])) for b in bands)


class Bench:
    def __init__(self, n_samples: int, seed: int = 5):
        from straylight.catalog.build import make_catalog
        from straylight.config import load_campaign
        from straylight.model import BackgroundModel

        self.campaign = load_campaign()
        self.bands = list(self.campaign.bands)
        base = BackgroundModel(self.campaign)
        self.catalog, _ = make_catalog({b: base.context.band(b).response for b in self.bands})
        sc, los, g = random_samples(self.campaign, 12 * n_samples, seed=seed)
        obs = np.flatnonzero(g["observable"])[:n_samples]
        self.sat, self.los = sc.satellite_km[obs], los[obs]
        self.bodies = {k: v[obs] for k, v in sc.bodies_km.items()}
        self.geometry = {k: v[obs] for k, v in g.items()}
        self.n = len(obs)

    def stars(self, limit: float, faint: bool):
        from straylight.sources.stars_table import split_stars

        return split_stars(
            self.catalog["ra"],
            self.catalog["dec"],
            {b: self.catalog[f"mag_{b}"] for b in self.bands},
            limit,
            faint,
        )

    def model(
        self,
        n_gamma=24,
        n_psi=48,
        door_blocks=(24, 24),
        n_aperture_door=256,
        pst_step=(0.5, 5.0),
        lut_steps=None,
        tolerance=None,
    ):
        """A component model with these knobs; ``lut_steps`` (deg): the earthshine look-up table
        with these node steps instead of the direct sum (built on first use, cached);
        ``tolerance``: models.tolerance (with the direct sum it sizes only the bright stars'
        skipping on their bound; 1e-12 skips nothing)."""

        from straylight.config import campaign_from_dict
        from straylight.model import BackgroundModel
        from straylight.optics.pst import PST, default_pst_grid

        raw = self.campaign.config_mapping()
        if tolerance is not None:
            raw["models"]["tolerance"] = tolerance
        es = raw["models"]["earthshine"]
        if lut_steps is None:
            es["method"] = "direct"
        else:
            es["method"] = "lut"
            es["lut"] = dict(
                zip(("sun_zenith_step_deg", "los_zenith_step_deg", "azimuth_step_deg"), lut_steps)
            )
        cm = BackgroundModel(campaign_from_dict(raw, self.campaign.path))
        off = cm.earth_grid
        es = replace(
            off.earthshine,
            n_gamma=n_gamma,
            n_psi=n_psi,
            door_blocks=tuple(door_blocks),
            n_aperture_door=n_aperture_door,
        )
        pst = off.pst if tuple(pst_step) == (0.5, 5.0) else PST(*default_pst_grid(*pst_step), source="bench")
        transfer = replace(off.transfer, pst=pst)
        cm.context.__dict__["offfield"] = transfer  # before any source reads them
        cm.source("sunlit_earth").engine.__dict__["grid"] = replace(off, transfer=transfer, earthshine=es)
        return cm

    def evaluate(self, cm, stars, sl=slice(None)):
        bodies = {k: v[sl] for k, v in self.bodies.items()}
        g = {k: v[sl] for k, v in self.geometry.items()}
        return cm.evaluate(self.sat[sl], bodies, self.los[sl], g, self.bands, stars)


DEFAULT = dict(n_gamma=24, n_psi=48, door_blocks=(24, 24), n_aperture_door=256, pst_step=(0.5, 5.0))
REFERENCE = dict(
    n_gamma=96, n_psi=192, door_blocks=(48, 48), n_aperture_door=512, pst_step=(0.1, 1.0), tolerance=1e-12
)
DEFAULT_STARS = (2.0, True)
REFERENCE_STARS = (99.0, False)  # every catalog star summed with the exact transfer


def sweep(bench, ref, name, settings):
    rows = []
    for label, kwargs, stars in settings:
        cm = bench.model(**kwargs)
        info = cm.source("sunlit_earth").model  # builds the look-up table if one is asked for (or loads it)
        res, dt = timed(lambda: bench.evaluate(cm, stars))
        err = max_rel_error(res, ref, bench.bands)
        row = {"setting": label, "max_rel_error": err, "seconds_per_sample": dt / bench.n}
        extra = ""
        if info["method"] == "lut":
            # the tables' own recorded build times: a cached table loads in milliseconds
            mlut = cm.source("moonlit_earth").model["lut"]
            row["lut_build_seconds"] = info["lut"].build_seconds + (
                mlut.build_seconds if mlut is not None else 0.0
            )
            row["lut_validation_max_rel_error"] = info["lut_validation_max_rel_error"]
            extra = f"  (table built in {row['lut_build_seconds']:.0f} s)"
        rows.append(row)
        print(f"  {name:14s} {label:24s} error {err:9.2e}   {dt / bench.n * 1e3:8.3f} ms/sample{extra}")
    return rows


def cube_model(
    base, campaign: dict | None = None, earthshine: dict | None = None, models: dict | None = None, **model_kw
):
    """A campaign from ``base`` with ``campaign``, ``models.earthshine`` and ``models``
    overrides, and its BackgroundModel for cube-sized runs, the earthshine table built or loaded
    before timing."""

    from straylight.config import campaign_from_dict
    from straylight.model import BackgroundModel

    raw = base.config_mapping()
    raw["campaign"].update(campaign or {})
    raw["models"].update(models or {})
    raw["models"].setdefault("earthshine", {}).update(earthshine or {})
    c = campaign_from_dict(raw, base.path)
    model = BackgroundModel(c, **model_kw)
    model.source("sunlit_earth").model
    return c, model


def pareto_chart(name, rows, path, xlabel="seconds per sample (one core, all bands)"):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = np.array([r["seconds_per_sample"] for r in rows])
    y = np.array([max(r["max_rel_error"], 1e-9) for r in rows])
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.loglog(x, y, "o", color="C0")
    order = np.argsort(x)
    front, best = [], np.inf
    for i in order:  # Pareto front: nothing cheaper is as accurate
        if y[i] < best:
            front.append(i)
            best = y[i]
    ax.loglog(x[front], y[front], "-", color="C1", label="Pareto front")
    for xi, yi, r in zip(x, y, rows):
        ax.annotate(r["setting"], (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.axhline(0.01, color="grey", ls="--", lw=0.8, label="default tolerance 1 %")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("max |error| / total background")
    ax.set_title(f"straylight: {name}")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
