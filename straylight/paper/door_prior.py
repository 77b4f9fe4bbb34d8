"""The angles at which the Earth's light reaches the door's inner face, for the door's
reflectance prior (seed paper sects. 2.2, 3.2; docs/pst.md "The door's prior").

The door path re-emits the light the door's inner face receives from the Earth (EA2). The
reflectance that matters is the coating's at the incidence angles that light arrives at, and
towards the aperture. This module gives the distribution of those incidence angles, weighted by
the light each Earth block delivers to the door (luminance x solid angle x cos(incidence) x the
share of the door the body leaves lit), over the sunlit orbital phases of the paper's scenario
(:mod:`straylight.paper.tail_calibration`), and the angle between the specular direction and
the direction back to the aperture.
"""

from __future__ import annotations

import numpy as np

from straylight.config import Campaign
from straylight.paper.tail_calibration import PhaseGrid, scenario_pointings
from straylight.sky.frames import telescope_frame
from straylight.sky.observing import sample_geometry, scene
from straylight.sky.vectors import dot, radec_to_unit, unit

__all__ = ["door_incidence"]


def door_incidence(
    campaign: Campaign, phases: PhaseGrid, nside: int, min_limb_deg: float = 80.0, quantiles=(0.16, 0.5, 0.84)
) -> dict:
    """Weighted quantiles of the incidence angle of the Earth's light on the door's inner face
    (the sunlit Earth), per door state, at the sunlit-limb pointings at least ``min_limb_deg``
    from the bright limb (where the door carries most of the earthshine, docs/pst.md).

    Parameters
    ----------
    campaign : Campaign
        The campaign (instrument's door and body, Earth grid).
    phases : PhaseGrid
        Orbital phases; only the sunlit ones are used.
    nside : int
        HEALPix resolution of the pointings.
    min_limb_deg : float
        Keep pointings at least this far from the bright limb, deg.
    quantiles : sequence of float
        Quantiles of the weighted distribution.

    Returns
    -------
    dict
        Per door state (opening, deg): ``incidence_deg`` (quantile -> deg), ``specular_to_aperture_deg``
        (quantile -> the angle between the specular reflection and the direction from the
        door's centre to the aperture's centre, deg), ``pointings``.
    """
    from straylight.model import BackgroundModel

    off = BackgroundModel(campaign).earth_grid  # the Earth grid over the transfer
    s = off.cap_settings(None)
    ra, dec = scenario_pointings(nside)
    los_all = radec_to_unit(ra, dec)
    lit = np.flatnonzero(phases.sunlit)
    bodies = scene(campaign.orbit, phases.time).bodies_km
    sun_km, moon_km = bodies["sun"][0], bodies["moon"][0]
    acc: dict = {}
    for p in lit:
        sat = phases.satellite_km[p]
        sc = type(scene(campaign.orbit, phases.time))(
            times=None,
            satellite_km=sat[None, :],
            bodies_km={k: v[:1] for k, v in bodies.items()},
        )
        g = sample_geometry(sc, ra, dec, campaign.earth.radius_km, campaign.constraints, grid=True)
        keep = np.asarray(g["limb_is_bright"] & (g["bright_limb_angle_deg"] >= min_limb_deg))[0]
        if not keep.any():
            continue
        los = los_all[keep]
        opening = np.asarray(g["door_opening_deg"])[0][keep]
        frame = telescope_frame(los, unit(sun_km - sat)[None, :])
        d, d_omega, _, mu_sun, _ = off._lit_cap(
            sat[None, :], campaign.earth.radius_km, s, sun_km[None, :], moon_km[None, :], True, False
        )
        d, d_omega, mu_sun = d[0], d_omega[0], mu_sun[0]  # (G, P, 3), (G, P)
        for state in off.door_states_deg:
            sel = opening == state
            if sel.any():
                _add_state(acc, off, state, frame, np.flatnonzero(sel), (d, d_omega, mu_sun))
    out = {}
    for state, (inc, spec, wt, n) in acc.items():
        inc, spec, wt = np.concatenate(inc), np.concatenate(spec), np.concatenate(wt)
        out[float(state)] = {
            "incidence_deg": _wquantiles(inc, wt, quantiles),
            "specular_to_aperture_deg": _wquantiles(spec, wt, quantiles),
            "pointings": int(n),
        }
    return out


def _add_state(acc: dict, off, state, frame, rows, cap: tuple) -> None:
    """Add to ``acc[state]`` the incidence angles on the door's inner face (deg), the angles of
    their specular reflections from the aperture (deg) and their weights, of the sunlit cap
    ``cap`` (block directions, solid angles sr, cos of the Sun's zenith) at the lines of sight
    ``rows`` of ``frame`` (the samples at door state ``state``)."""
    d, d_omega, mu_sun = cap
    q, n_in, w = off._door_weights[state]
    centre = np.sum(q * w[:, None], axis=0) / np.sum(w)
    to_ap = unit(-centre)
    for m in rows:
        dx = dot(d, frame.x[m])
        dy = dot(d, frame.y[m])
        dz = dot(d, frame.z[m])  # noqa: E702
        v = np.stack([dx, dy, dz], -1)  # block directions in the telescope frame
        cos_inc = v @ n_in
        theta = np.degrees(np.arctan2(np.hypot(dx, dy), dz))
        phi = np.degrees(np.arctan2(dy, dx)) % 360.0
        wt = mu_sun * d_omega * np.maximum(cos_inc, 0.0) * off.door_lit_fraction(state, theta, phi)
        ok = wt > 0
        if not ok.any():
            continue
        k = -v[ok]  # propagation: from the Earth block towards the door
        spec = k - 2.0 * (k @ n_in)[:, None] * n_in
        a = acc.setdefault(state, [[], [], [], 0])
        a[0].append(np.degrees(np.arccos(np.clip(cos_inc[ok], -1, 1))))
        a[1].append(np.degrees(np.arccos(np.clip(spec @ to_ap, -1, 1))))
        a[2].append(wt[ok])
        a[3] += 1


def _wquantiles(x, w, q) -> dict:
    """Quantiles ``q`` of ``x`` weighted by ``w``."""
    o = np.argsort(x)
    c = np.cumsum(w[o]) / np.sum(w)
    return {f"p{round(100 * k)}": float(np.interp(k, c, x[o])) for k in q}
