"""The assumption envelope's members: joint values of the PST's tail, the door's reflectance and
the body's radius that keep the paper's median crossing (sect. 3.3: CSST reaches HST's 20-deg
earthshine 70 deg from the bright limb) within a stated tolerance (docs/pst.md, "The envelope's
members"; :mod:`straylight.model.envelope` re-evaluates the model at the two ends).

For each body radius and door reflectance of a grid over their prior ranges, the tails at which
the median crossing over the sunlit phases is the target and the target +/- the tolerance are
found (:mod:`straylight.paper.tail_calibration`: the door path is linear in the reflectance, each
path log-linear in the tail between the computed tails). Every such (tail, door, body) is a
member. Each member's earthshine in the observable sky (the sunlit-limb pointings at least the
avoidance's 80 deg from the bright limb, seed paper sect. 1) ranks them: the brightest is the
pessimistic end, the darkest the optimistic one.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from straylight.config import Campaign
from straylight.config.loading import deep_merge
from straylight.paper.scenarios import PhaseSampling
from straylight.paper.tail_calibration import (
    _log_lerp,
    _median_crossing,
    orbit_phases,
    phase_crossings,
    phase_earthshine,
)

__all__ = ["campaign_with_body", "envelope_members"]


def _body_door_members(grid: dict, level_mag: float, goals, far, member: tuple) -> list:
    """The members of one body radius and door reflectance: at each goal the median crossing
    brackets (deg), the tail (every 0.02 dex across ``grid``'s) that gives it, with the mean
    earthshine (e-/s/pix) at the pointings ``far``; ``member`` (reflectance, its ratio to the
    campaign's, body radius m)."""
    r, scale, body = member
    tails = grid["tails_log10"]
    fine = np.round(np.arange(tails.min(), tails.max() + 1e-9, 0.02), 2)
    med = np.array(
        [_median_crossing(phase_crossings(grid, level_mag, t, scale)["crossing_deg"]) for t in fine]
    )
    out = []
    for goal in goals:
        if not (np.min(med) <= goal <= np.max(med[np.isfinite(med)], initial=-np.inf)):
            continue
        k = int(np.argmin(np.abs(med - goal)))
        t = float(fine[k])
        e = _log_lerp(tails, grid["direct_e_per_s_per_pix"], t) + scale * _log_lerp(
            tails, grid["door_e_per_s_per_pix"], t
        )
        out.append(
            {
                "tail_log10_at_90deg": t,
                "door_reflectance": r,
                "body_radius_m": body,
                "goal_deg": float(goal),
                "median_crossing_deg": float(med[k]),
                "observable_earthshine_e_per_s_per_pix": float(np.mean(e[far])),
            }
        )
    return out


def campaign_with_body(campaign: Campaign, body_radius_m: float) -> Campaign:
    """A copy of ``campaign`` whose telescope body has radius ``body_radius_m`` (m).

    Parameters
    ----------
    campaign : Campaign
        The campaign.
    body_radius_m : float
        The body's radius, m.

    Returns
    -------
    Campaign
    """
    inst = campaign.instrument_mapping()
    body = dict(inst["door_geometry"]["body_radius_m"])
    body["value"] = float(body_radius_m)
    return Campaign(
        settings=campaign.settings,
        instrument=deep_merge(inst, {"door_geometry": {"body_radius_m": body}}),
        path=campaign.path,
        instrument_path=campaign.instrument_path,
    )


def envelope_members(
    campaign: Campaign,
    level_mag: float,
    target_deg: float,
    tolerance_deg: float,
    doors,
    bodies_m,
    sampling: PhaseSampling = PhaseSampling(60.0, 10.0, 8, (-8.5, -9.25, -10.0, -10.75, -11.5)),
    observable_limb_deg: float = 80.0,
) -> dict:
    """The members and the ends.

    Parameters
    ----------
    campaign : Campaign
        The campaign (its door's reflectance is the one the door path is computed at).
    level_mag : float
        HST's earthshine at its 20-deg limit, V mag/arcsec2.
    target_deg, tolerance_deg : float
        The paper's median crossing and the tolerance kept, deg.
    doors : sequence of float
        Door reflectances (dimensionless).
    bodies_m : sequence of float
        Body radii, m.
    sampling : PhaseSampling
        As :func:`~straylight.paper.tail_calibration.calibrate_tail`.
    observable_limb_deg : float
        The bright-limb angle from which the members' earthshine is ranked, deg.

    Returns
    -------
    dict
        ``members``: list of dicts (``tail_log10_at_90deg`` dex, ``door_reflectance``,
        ``body_radius_m`` m, ``goal_deg``, ``median_crossing_deg`` deg,
        ``observable_earthshine_e_per_s_per_pix``: the mean V earthshine over the sunlit phases'
        pointings beyond ``observable_limb_deg``), ``pessimistic`` and ``optimistic`` (the
        brightest and darkest member), and the inputs.
    """
    raan_step_deg, u_step_deg, nside, tails_log10, time = dataclasses.astuple(sampling)
    r0 = float(campaign.instrument_settings.door_geometry.reflectance.value)
    phases = orbit_phases(campaign, raan_step_deg, u_step_deg, time)
    goals = (target_deg - tolerance_deg, target_deg, target_deg + tolerance_deg)
    members = []
    for body in bodies_m:
        grid = phase_earthshine(campaign_with_body(campaign, body), phases, tails_log10, nside)
        far = grid["limb_angle_deg"] >= observable_limb_deg
        for r in doors:
            members += _body_door_members(grid, level_mag, goals, far, (float(r), float(r) / r0, float(body)))
    brightness = [m["observable_earthshine_e_per_s_per_pix"] for m in members]
    return {
        "members": members,
        "pessimistic": members[int(np.argmax(brightness))],
        "optimistic": members[int(np.argmin(brightness))],
        "target_deg": float(target_deg),
        "tolerance_deg": float(tolerance_deg),
        "observable_limb_deg": float(observable_limb_deg),
        "level_v_mag_per_arcsec2": float(level_mag),
        "raan_step_deg": float(raan_step_deg),
        "u_step_deg": float(u_step_deg),
        "nside": int(nside),
        "tails_computed_log10": [float(t) for t in tails_log10],
        "time": time,
    }
