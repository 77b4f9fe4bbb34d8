"""The default PST's large-angle tail calibrated over the satellite's sunlit orbital phases
(seed paper sect. 3.3; docs/pst.md).

The paper's scenario (2026-01-01 00:50 UTC, CSST and HST at the same pointings, "situated within
the sunlit region") does not give CSST's orbital phase, so it is run over circular orbits of the
campaign's altitude and inclination: the ascending node (raan) and the argument of latitude u at
the scenario's time on uniform grids (uniform in time along an orbit, every node alike).

* A phase is **sunlit** when the Sun is above the satellite's local horizontal (zenith angle
  at the satellite < 90 deg).
* Pointings: HEALPix pixel centres with |Dec| <= 75 deg (the paper's range, evenly over the
  sky); the sunlit-limb ones (:func:`~straylight.paper.scenarios.sunlit_limb`) are kept.
* CSST's earthshine (direct + door, V) is the direct sum over the Earth grid (the reference,
  whatever ``models.earthshine.method`` says). Where its median in 10-deg bins of the
  bright-limb angle falls to HST's earthshine at HST's 20-deg limit is the **crossing angle**
  (:func:`~straylight.paper.scenarios.crossing_angle_deg`; NaN if it never does).
* **The rule:** the tail (log10 PST at 90 deg, log-linear from the 30-deg anchor) is the value
  at which the median crossing over the sunlit phases is the paper's 70 deg, a phase that
  never crosses counting as beyond every angle. The crossings' percentiles at that value are
  the spread the tail leaves.

The earthshine is computed at a few tails, all phases at once; each path is interpolated in log
between them, so every phase's crossing follows for any tail, and so does the rule's tail.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from straylight.config import Campaign
from straylight.config.loading import deep_merge
from straylight.errors import ConfigError, InputError
from straylight.paper.scenarios import (
    HST_BRIGHT_LIMB_LIMIT_DEG,
    LIMB_BIN_DEG,
    SCENARIO_TIME,
    PhaseSampling,
    _median_crossing,
    _percentiles,
    binned_median,
    crossing_angle_deg,
)
from straylight.sky.observing import Scene, sample_geometry, scene
from straylight.sky.orbit import CircularOrbit
from straylight.sky.vectors import radec_to_unit

__all__ = [
    "PAPER_CROSSING_DEG",
    "PAPER_DEC_LIMIT_DEG",
    "PhaseGrid",
    "orbit_phases",
    "sun_zenith_at_satellite_deg",
    "scenario_pointings",
    "campaign_with_tail",
    "phase_earthshine",
    "earthshine_mag",
    "phase_crossings",
    "calibrate_tail",
    "phase_tails",
    "default_phase_crossing",
]

#: the paper's conclusion (sect. 3.3): CSST must stay at least 70 deg from the bright limb to
#: see the earthshine HST sees 20 deg from it, deg
PAPER_CROSSING_DEG = 70.0
#: the paper's pointing grid reaches Dec -75 to +75 deg (sect. 3.3)
PAPER_DEC_LIMIT_DEG = 75.0


@dataclasses.dataclass(frozen=True)
class PhaseGrid:
    """Orbital phases at one instant: circular orbits of the campaign's altitude and
    inclination.

    Attributes
    ----------
    raan_deg, arg_latitude_deg : ndarray, shape (n,)
        Each phase's ascending node and argument of latitude at ``time``, deg.
    satellite_km : ndarray, shape (n, 3)
        Geocentric GCRS satellite positions, km.
    sun_zenith_deg : ndarray, shape (n,)
        The Sun's zenith angle at the satellite, deg.
    time : str
        UTC, ISO 8601.
    """

    raan_deg: np.ndarray
    arg_latitude_deg: np.ndarray
    satellite_km: np.ndarray
    sun_zenith_deg: np.ndarray
    time: str

    @property
    def sunlit(self) -> np.ndarray:
        """Whether each phase is sunlit: the Sun above the satellite's local horizontal."""
        return self.sun_zenith_deg < 90.0


def sun_zenith_at_satellite_deg(satellite_km, sun_km) -> np.ndarray:
    """The Sun's zenith angle at the satellite, deg: the angle between the satellite's
    geocentric direction and the direction from it to the Sun.

    Parameters
    ----------
    satellite_km, sun_km : array_like, shape (..., 3)
        Geocentric positions, km.

    Returns
    -------
    ndarray, shape (...)
        Deg, 0-180.
    """
    sat = np.asarray(satellite_km, float)
    to_sun = np.asarray(sun_km, float) - sat
    c = np.sum(sat * to_sun, -1) / (np.linalg.norm(sat, axis=-1) * np.linalg.norm(to_sun, axis=-1))
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def orbit_phases(
    campaign: Campaign, raan_step_deg: float, u_step_deg: float, time: str = SCENARIO_TIME
) -> PhaseGrid:
    """The grid of orbital phases at ``time``: raan and u each from 0 in uniform steps.

    Parameters
    ----------
    campaign : Campaign
        Its circular orbit's altitude and inclination and its Earth are used.
    raan_step_deg, u_step_deg : float
        Steps of the ascending node and of the argument of latitude, deg (each divides 360).
    time : str
        UTC, ISO 8601.

    Returns
    -------
    PhaseGrid
        raan-major order (every u of the first node, then the next node).

    Raises
    ------
    ConfigError
        When the campaign's orbit is not circular.
    """
    base = campaign.orbit
    if not isinstance(base, CircularOrbit):
        raise ConfigError("orbit.model: the tail calibration needs a circular orbit (orbit.model: circular)")
    raan, u = np.meshgrid(
        np.arange(0.0, 360.0 - 1e-9, raan_step_deg), np.arange(0.0, 360.0 - 1e-9, u_step_deg), indexing="ij"
    )
    raan, u = raan.ravel(), u.ravel()
    orbits = [dataclasses.replace(base, raan_deg=o, arg_latitude_deg=a, epoch=time) for o, a in zip(raan, u)]
    sat = np.array([o.position_gcrs_km(time) for o in orbits]).reshape(-1, 3)
    sun = scene(base, time).bodies_km["sun"][0]
    return PhaseGrid(raan, u, sat, sun_zenith_at_satellite_deg(sat, sun), time)


def scenario_pointings(nside: int) -> tuple[np.ndarray, np.ndarray]:
    """Pointings spread evenly over the paper's sky: HEALPix pixel centres (ring order) with
    |Dec| <= :data:`PAPER_DEC_LIMIT_DEG`.

    Parameters
    ----------
    nside : int
        HEALPix resolution.

    Returns
    -------
    ra_deg, dec_deg : ndarray, shape (n,)
        ICRS, deg.
    """
    import healpy as hp

    ra, dec = hp.pix2ang(nside, np.arange(hp.nside2npix(nside)), lonlat=True)
    keep = np.abs(dec) <= PAPER_DEC_LIMIT_DEG
    return ra[keep], dec[keep]


def campaign_with_tail(campaign: Campaign, tail_log10_at_90deg: float) -> Campaign:
    """A copy of ``campaign`` whose default PST has ``tail_log10_at_90deg`` and whose sunlit
    earthshine is the direct sum (the reference; no table to build per tail).

    Parameters
    ----------
    campaign : Campaign
        The campaign.
    tail_log10_at_90deg : float
        log10 PST (azimuthal mean) at 90 deg.

    Returns
    -------
    Campaign
    """
    # the file as written, not the typed settings: a campaign is made from it with one value
    # changed, and its typed settings parsed from that as from any instrument file
    inst = campaign.instrument_mapping()
    tail = dict(inst.get("pst", {}).get("tail_log10_at_90deg") or {"unit": "dex", "source": "calibration"})
    tail["value"] = float(tail_log10_at_90deg)
    return Campaign(
        config=deep_merge(campaign.config_mapping(), {"models": {"earthshine": {"method": "direct"}}}),
        instrument=deep_merge(inst, {"pst": {"tail_log10_at_90deg": tail}}),
        path=campaign.path,
        instrument_path=campaign.instrument_path,
    )


def phase_earthshine(campaign: Campaign, phases: PhaseGrid, tails_log10, nside: int, band: str = "V") -> dict:
    """CSST's earthshine at the sunlit-limb pointings of the sunlit phases, for each tail.

    Parameters
    ----------
    campaign : Campaign
        The campaign (instrument, Earth, orbit's altitude and inclination).
    phases : PhaseGrid
        The phases; only the sunlit ones are evaluated.
    tails_log10 : sequence of float
        Tail values, log10 PST at 90 deg.
    nside : int
        HEALPix resolution of the pointings (:func:`scenario_pointings`).
    band : str
        Band name.

    Returns
    -------
    dict
        ``phase`` (index into ``phases`` of each sample, shape (n,)), ``limb_angle_deg`` (deg,
        (n,)), ``sun_angle_deg`` (the Sun's off-axis angle, deg, (n,)), ``tails_log10`` (shape
        (k,)), ``direct_e_per_s_per_pix`` and ``door_e_per_s_per_pix`` (the earthshine's two
        paths, e-/s/pix, shape (k, n)), ``mag_of_one_e_per_s_per_pix`` (the band's AB
        mag/arcsec2 of 1 e-/s/pix), ``pointings`` (per phase evaluated), ``band``.
    """
    from straylight.model import BackgroundModel

    ra, dec = scenario_pointings(nside)
    lit = np.flatnonzero(phases.sunlit)
    sun_moon = scene(campaign.orbit, phases.time).bodies_km
    bodies = {k: np.repeat(v[:1], lit.size, axis=0) for k, v in sun_moon.items()}
    sc = Scene(times=None, satellite_km=phases.satellite_km[lit], bodies_km=bodies)
    g = sample_geometry(sc, ra, dec, campaign.earth.radius_km, campaign.constraints, grid=True)  # (L, P)
    keep = g["limb_is_bright"] & (g["earth_limb_angle_deg"] > 0)
    li, pi = np.nonzero(keep)
    los = radec_to_unit(ra, dec)[pi]
    sat = phases.satellite_km[lit][li]
    geom = {k: np.asarray(v)[keep] for k, v in g.items() if np.shape(v) == keep.shape}
    tails = np.asarray(tails_log10, float)
    direct, door = np.empty((tails.size, li.size)), np.empty((tails.size, li.size))
    # one phase at a time: its pointings share the satellite, the Sun and the Moon, so the
    # earthshine takes the compiled one-scene sums
    starts = np.flatnonzero(np.r_[True, np.diff(li) != 0])
    ends = np.r_[starts[1:], li.size]
    mag_of_one = float("nan")
    for t, tail in enumerate(tails):
        model = BackgroundModel(campaign_with_tail(campaign, tail), build_workers=1)
        for a, e in zip(starts, ends):
            n = e - a
            b = {k: np.broadcast_to(v[0], (n, 3)) for k, v in sun_moon.items()}
            comps = model.evaluate(
                np.broadcast_to(sat[a], (n, 3)), b, los[a:e], {k: v[a:e] for k, v in geom.items()}, [band]
            )[band]
            direct[t, a:e], door[t, a:e] = comps["earthshine_direct"], comps["earthshine_door"]
            mag_of_one = float(model.mag_per_arcsec2(np.array([1.0]), band)[0])
    return {
        "phase": lit[li],
        "limb_angle_deg": geom["bright_limb_angle_deg"],
        "sun_angle_deg": geom["sun_angle_deg"],
        "tails_log10": tails,
        "direct_e_per_s_per_pix": direct,
        "door_e_per_s_per_pix": door,
        "mag_of_one_e_per_s_per_pix": mag_of_one,
        "pointings": np.bincount(lit[li], minlength=phases.raan_deg.size),
        "band": band,
    }


def _log_lerp(tails, values, tail_log10):
    """``values`` (k, n) >= 0 at ``tail_log10``, linear in log between the two nearest tails
    (extrapolated outside them); zeros where both are zero."""
    if tails.size == 1:
        return values[0]
    order = np.argsort(tails)
    tails, values = tails[order], values[order]
    k = int(np.clip(np.searchsorted(tails, tail_log10) - 1, 0, tails.size - 2))
    w = (tail_log10 - tails[k]) / (tails[k + 1] - tails[k])
    lo, hi = np.log(np.maximum(values[k], 1e-300)), np.log(np.maximum(values[k + 1], 1e-300))
    return np.where((values[k] > 0) | (values[k + 1] > 0), np.exp(lo + w * (hi - lo)), 0.0)


def earthshine_mag(result: dict, tail_log10: float, door_scale: float = 1.0) -> np.ndarray:
    """Each sample's earthshine at ``tail_log10``, AB mag/arcsec2 (inf where it is 0).

    Parameters
    ----------
    result : dict
        :func:`phase_earthshine`'s.
    tail_log10 : float
        The tail, log10 PST at 90 deg: each path is interpolated in log between the computed
        tails.
    door_scale : float
        Factor on the door path (it is linear in the door's reflectance), dimensionless.

    Returns
    -------
    ndarray, shape (n,)
    """
    t = result["tails_log10"]
    e = _log_lerp(t, result["direct_e_per_s_per_pix"], tail_log10) + door_scale * _log_lerp(
        t, result["door_e_per_s_per_pix"], tail_log10
    )
    with np.errstate(divide="ignore"):
        return result["mag_of_one_e_per_s_per_pix"] - 2.5 * np.log10(e)


def phase_crossings(
    result: dict,
    level_mag: float,
    tail_log10: float,
    door_scale: float = 1.0,
    min_sun_angle_deg: float | None = None,
) -> dict:
    """Each evaluated phase's crossing angle at ``tail_log10``.

    Parameters
    ----------
    result : dict
        :func:`phase_earthshine`'s.
    level_mag : float
        HST's earthshine at its 20-deg limit, V mag/arcsec2.
    tail_log10 : float
        The tail, log10 PST at 90 deg.
    door_scale : float
        Factor on the door path (:func:`earthshine_mag`).
    min_sun_angle_deg : float or None
        Keep only pointings at least this far from the Sun (deg; None: all, as the paper's
        grid).

    Returns
    -------
    dict
        ``phase`` (indices, shape (m,)), ``crossing_deg`` (deg, NaN where the median never falls
        to the level), ``last_bin_deg`` (the upper edge of each phase's last bin with
        pointings, deg), ``min_pointings_per_bin`` (the fewest pointings in a bin of 0-90 deg at
        each phase), ``bins`` (per phase: centres, medians, counts).
    """
    mags = earthshine_mag(result, tail_log10, door_scale)
    keep = np.ones(mags.size, bool)
    if min_sun_angle_deg is not None:
        keep = result["sun_angle_deg"] >= min_sun_angle_deg
    phases = np.unique(result["phase"])
    cross, fewest, bins, last = [], [], [], []
    for p in phases:
        sel = (result["phase"] == p) & keep
        c, m, n = binned_median(result["limb_angle_deg"][sel], mags[sel])
        cross.append(crossing_angle_deg(c, m, level_mag) if c.size else float("nan"))
        fewest.append(int(n[c < 90.0].min()) if np.any(c < 90.0) else 0)
        last.append(float(c[-1] + LIMB_BIN_DEG / 2) if c.size else 0.0)
        bins.append((c, m, n))
    return {
        "phase": phases,
        "crossing_deg": np.array(cross),
        "last_bin_deg": np.array(last),
        "min_pointings_per_bin": np.array(fewest),
        "bins": bins,
    }


def calibrate_tail(
    campaign: Campaign,
    level_mag: float,
    target_deg: float = PAPER_CROSSING_DEG,
    sampling: PhaseSampling = PhaseSampling(45.0, 10.0, 10, (-9.0, -9.75, -10.5)),
    band: str = "V",
    min_sun_angle_deg: float = 50.0,
) -> dict:
    """The tail that makes the median sunlit crossing ``target_deg``, and the spread it leaves.

    Parameters
    ----------
    campaign : Campaign
        The campaign (instrument, Earth, orbit's altitude and inclination).
    level_mag : float
        HST's earthshine at its 20-deg limit, V mag/arcsec2.
    target_deg : float
        The median crossing the rule asks for, deg.
    sampling : PhaseSampling
        The phase grid's steps, the pointings' HEALPix resolution, the time and the tails the
        earthshine is computed at; the solution is interpolated between them (each path
        log-linear in the tail), rounded to 0.01 dex, and computed again there: the crossings
        reported are that computation's.
    band : str
        Band name.
    min_sun_angle_deg : float
        The Sun avoidance of the variant that keeps only observable-by-the-Sun pointings (the
        paper's door states need the Sun at least 50 deg off axis, sect. 2.2), deg.

    Returns
    -------
    dict
        ``rule``; ``tail_log10_at_90deg`` (the solution, dex); ``median_crossing_deg``;
        ``crossing_percentiles_deg`` (p5-p95 over the sunlit phases, deg; inf: never crosses);
        per sunlit phase ``crossing_deg``, ``raan_deg``, ``arg_latitude_deg``,
        ``sun_zenith_deg`` and ``phase_tail_log10`` (the tail that phase alone would give:
        :func:`phase_tails`), with ``phase_tail_percentiles``; ``never_crossing``;
        ``n_phases``, ``n_sunlit``; ``min_pointings_per_bin`` and ``median_pointings_per_bin``
        (bins of 0-90 deg); ``median_crossing_by_tail``; ``variants`` (the crossings with the
        door path halved and with the Sun avoidance); and the inputs.  ``_result``,
        ``_crossings`` and ``_phases`` keep the arrays for figures.

    Raises
    ------
    InputError
        When the median crossings at ``tails_log10`` do not bracket ``target_deg``.
    """
    raan_step_deg, u_step_deg, nside, tails_log10, time = dataclasses.astuple(sampling)
    phases = orbit_phases(campaign, raan_step_deg, u_step_deg, time)
    grid = phase_earthshine(campaign, phases, tails_log10, nside, band)
    tail, fine, fine_med = _fine_crossings(grid, level_mag, target_deg)
    res = phase_earthshine(campaign, phases, [tail], nside, band)
    cr = phase_crossings(res, level_mag, tail)
    return {
        "rule": (
            f"the median over sunlit orbital phases of the limb angle at which CSST's binned median "
            f"earthshine ({band}) falls to HST's at {HST_BRIGHT_LIMB_LIMIT_DEG:g} deg "
            f"({level_mag:.2f} mag/arcsec2) is {target_deg:g} deg (seed paper sect. 3.3)"
        ),
        "tail_log10_at_90deg": tail,
        "median_crossing_deg": _median_crossing(cr["crossing_deg"]),
        "crossing_percentiles_deg": _percentiles(cr["crossing_deg"]),
        **_phase_record(cr, phases, phase_tails(grid, level_mag, target_deg)[1]),
        "median_crossing_by_tail": {
            f"{t:.2f}": float(m) for t, m in zip(fine, fine_med) if abs(t * 4 - round(t * 4)) < 1e-6
        },
        "variants": _variants(res, level_mag, tail, min_sun_angle_deg),
        "level_v_mag_per_arcsec2": float(level_mag),
        "target_deg": float(target_deg),
        "raan_step_deg": float(raan_step_deg),
        "u_step_deg": float(u_step_deg),
        "nside": int(nside),
        "tails_computed_log10": grid["tails_log10"].tolist(),
        "time": time,
        "band": band,
        "_result": res,
        "_grid": grid,
        "_crossings": cr,
        "_phases": phases,
    }


def _fine_crossings(grid: dict, level_mag: float, target_deg: float) -> tuple:
    """The tail (every 0.01 dex across ``grid``'s) whose median crossing is nearest
    ``target_deg``, the tails and their median crossings (deg); InputError unbracketed."""
    tails = grid["tails_log10"]
    fine = np.round(np.arange(tails.min(), tails.max() + 1e-9, 0.01), 2)
    fine_med = np.array([_median_crossing(phase_crossings(grid, level_mag, t)["crossing_deg"]) for t in fine])
    if not (np.nanmin(fine_med) <= target_deg <= np.max(fine_med)):
        raise InputError(
            f"median crossings {fine_med[0]:.1f}-{fine_med[-1]:.1f} deg at tails {tails.min()}-{tails.max()} "
            f"do not bracket {target_deg} deg: widen tails_log10"
        )
    return float(fine[int(np.argmin(np.abs(fine_med - target_deg)))]), fine, fine_med


def _phase_record(cr: dict, phases: PhaseGrid, own) -> dict:
    """Per sunlit phase its crossing (deg), orbit, Sun zenith and own tail (``own``), with counts."""
    lit = cr["phase"]
    return {
        "crossing_deg": cr["crossing_deg"],
        "raan_deg": phases.raan_deg[lit],
        "arg_latitude_deg": phases.arg_latitude_deg[lit],
        "sun_zenith_deg": phases.sun_zenith_deg[lit],
        "never_crossing": int(np.isnan(cr["crossing_deg"]).sum()),
        "latest_crossing_deg": _percentiles(cr["crossing_deg"], (100,))["p100"],  # a figure: sets nothing
        "phase_tail_log10": own,
        "phase_tail_percentiles": _percentiles(own),
        "n_phases": int(phases.raan_deg.size),
        "n_sunlit": int(lit.size),
        "min_pointings_per_bin": int(cr["min_pointings_per_bin"].min()),
        "median_pointings_per_bin": float(np.median(np.concatenate([n[c < 90.0] for c, _, n in cr["bins"]]))),
    }


def _variants(res: dict, level_mag: float, tail: float, min_sun_angle_deg: float) -> dict:
    """The crossings (deg) at ``tail`` with the door path halved and with the Sun avoidance."""
    variants = {}
    for name, kw in (
        ("door_path_halved", {"door_scale": 0.5}),
        (f"sun_at_least_{min_sun_angle_deg:g}_deg", {"min_sun_angle_deg": min_sun_angle_deg}),
    ):
        v = phase_crossings(res, level_mag, tail, **kw)["crossing_deg"]
        variants[name] = {
            "median_crossing_deg": _median_crossing(v),
            "crossing_percentiles_deg": _percentiles(v),
            "never_crossing": int(np.isnan(v).sum()),
        }
    return variants


def phase_tails(result: dict, level_mag: float, target_deg: float = PAPER_CROSSING_DEG, step: float = 0.01):
    """Each evaluated phase's own tail: the tail at which that phase alone crosses at
    ``target_deg`` (the tail the calibration would give had the paper's scenario been at that
    phase), on a grid of ``step`` dex within the computed tails.

    Parameters
    ----------
    result : dict
        :func:`phase_earthshine`'s.
    level_mag : float
        HST's earthshine at its 20-deg limit, V mag/arcsec2.
    target_deg : float
        The crossing, deg.
    step : float
        Grid step of the tail, dex.

    Returns
    -------
    phase : ndarray, shape (m,)
        Phase indices.
    tail_log10 : ndarray, shape (m,)
        dex; -inf where the phase crosses beyond ``target_deg`` at every computed tail, +inf
        where it crosses before it at every one.
    """
    tails = result["tails_log10"]
    fine = np.arange(tails.min(), tails.max() + step / 2, step)
    cross = np.array([phase_crossings(result, level_mag, t)["crossing_deg"] for t in fine])  # (k, m)
    c = np.where(np.isnan(cross), np.inf, cross)
    phase = np.unique(result["phase"])
    out = np.empty(phase.size)
    for j in range(phase.size):
        below = np.flatnonzero(c[:, j] <= target_deg)  # tails dark enough (crossing grows with the tail)
        if below.size == 0:
            out[j] = -np.inf
        elif below[-1] == fine.size - 1:
            out[j] = np.inf if below.size == fine.size else fine[-1]
        else:
            k = below[-1]  # crossing <= target at fine[k], > target at fine[k + 1]
            c0, c1 = c[k, j], c[k + 1, j]
            out[j] = fine[k] + (step * (target_deg - c0) / (c1 - c0) if np.isfinite(c1) else 0.0)
    return phase, out


def default_phase_crossing(
    campaign: Campaign, level_mag: float, tail_log10: float, nside: int = 16, time: str = SCENARIO_TIME
) -> dict:
    """The crossing at the campaign's own orbit (its configured phase), with the same pointings
    and rule, at ``tail_log10``.

    Parameters
    ----------
    campaign : Campaign
        The campaign (its circular orbit).
    level_mag : float
        HST's earthshine at its 20-deg limit, V mag/arcsec2.
    tail_log10 : float
        The tail, log10 PST at 90 deg.
    nside : int
        HEALPix resolution of the pointings.
    time : str
        UTC, ISO 8601.

    Returns
    -------
    dict
        ``raan_deg`` and ``arg_latitude_deg`` (the orbit's at ``time``, deg), ``sun_zenith_deg``
        (deg), ``sunlit``, ``crossing_deg`` (deg; NaN when it never crosses or is not sunlit).
    """
    base = campaign.orbit
    if not isinstance(base, CircularOrbit):
        raise ConfigError("orbit.model: the tail calibration needs a circular orbit (orbit.model: circular)")
    dt_s = float((scene(base, time).times[0] - base.epoch_time).to_value("s"))
    raan = (base.raan_deg + np.degrees(base.nodal_rate_rad_s * dt_s)) % 360.0
    u = (base.arg_latitude_deg + np.degrees(base.arg_latitude_rate_rad_s * dt_s)) % 360.0
    sat = base.position_gcrs_km(time).reshape(1, 3)
    sun = scene(base, time).bodies_km["sun"][0]
    ph = PhaseGrid(np.array([raan]), np.array([u]), sat, sun_zenith_at_satellite_deg(sat, sun), time)
    cross = float("nan")
    if ph.sunlit[0]:
        res = phase_earthshine(campaign, ph, [tail_log10], nside)
        cross = float(phase_crossings(res, level_mag, tail_log10)["crossing_deg"][0])
    return {
        "raan_deg": float(raan),
        "arg_latitude_deg": float(u),
        "sun_zenith_deg": float(ph.sun_zenith_deg[0]),
        "sunlit": bool(ph.sunlit[0]),
        "crossing_deg": cross,
    }
