"""Shared by the benchmark scripts: random (time, pointing) samples of a campaign."""

import numpy as np


def random_samples(campaign, n: int, seed: int):
    """n random campaign times paired with n pointings uniform on the sky.

    Returns (scene, line-of-sight unit vectors (n, 3), observing geometry dict)."""
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    rng = np.random.default_rng(seed)
    sc = scene(campaign.orbit, campaign.times[rng.integers(0, len(campaign.times), n)])
    ra, dec = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))
    los = radec_to_unit(ra, dec)
    g = observing_geometry(sc.satellite_km, sc.bodies_km, los, campaign.earth.radius_km, campaign.constraints)
    return sc, los, g
