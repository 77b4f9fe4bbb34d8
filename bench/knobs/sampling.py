"""Sampling knobs of the survey: the time cadence (linear interpolation in time, plain and
error-checked adaptive) and the HEALPix nside (a pixel's value standing for every direction
inside it)."""

from __future__ import annotations

import time

import numpy as np

from .common import DEFAULT_STARS

#: the adaptive cadence accepts an interval when its computed midpoint is within this fraction
#: of itself from the straight line between the ends (assumption: a quarter of the 1 % default
#: tolerance, as the interior points between checks are not computed)
ADAPTIVE_CHECK_FRACTION = 0.0025


def adaptive_in_time(full, obs, door, step, check_fraction):
    """Error-checked adaptive time sampling of each pointing's series ``full`` (T, B, P),
    replayed on values already computed: samples every ``step`` (and the last) are computed;
    an interval between computed samples is split at its midpoint, which is computed; the two
    halves are filled by linear interpolation when the midpoint lies within ``check_fraction``
    of itself (every band) from the line between the ends and neither the observability nor
    the door state changes inside, else each half is split again.  Returns the (T, P) mask of
    computed samples and the series it gives."""
    n_t = full.shape[0]
    state = obs.astype(int) * 1000 + np.round(door).astype(int)  # a break where either changes
    knots = sorted(set(range(0, n_t, step)) | {n_t - 1})
    computed = np.zeros(obs.shape, bool)
    computed[knots] = True
    out = np.array(full)
    for p in range(full.shape[2]):
        y, s = full[:, :, p], state[:, p]
        todo = list(zip(knots[:-1], knots[1:]))
        while todo:
            a, b = todo.pop()
            if b - a <= 1:
                continue
            m = (a + b) // 2
            computed[m, p] = True
            line = y[a] + (y[b] - y[a]) * (m - a) / (b - a)
            if np.all(s[a : b + 1] == s[a]) and np.all(np.abs(line - y[m]) <= check_fraction * y[m]):
                for lo, hi in ((a, m), (m, b)):
                    inner = np.arange(lo + 1, hi)
                    out[inner, :, p] = y[lo] + (y[hi] - y[lo]) * ((inner - lo) / (hi - lo))[:, None]
            else:
                todo += [(a, m), (m, b)]
    return computed, out


def time_cadence_rows(bench):
    """Background over 6 h at 60 s for 40 random pointings; coarser cadences linearly
    interpolated in time, and the error-checked adaptive sampling (:func:`adaptive_in_time`)
    from each coarse cadence; error over samples observable at the fine cadence."""
    from astropy.time import Time, TimeDelta

    from straylight.model import BackgroundModel
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    c = bench.campaign
    cm = BackgroundModel(c)
    stars = bench.stars(*DEFAULT_STARS)
    t0 = Time("2026-01-01T00:00:00", scale="utc")
    fine_s = 60.0
    times = t0 + TimeDelta(np.arange(0, 6 * 3600 + 1, fine_s), format="sec")
    rng = np.random.default_rng(2)
    ra, dec = rng.uniform(0, 360, 40), np.degrees(np.arcsin(rng.uniform(-1, 1, 40)))
    los = radec_to_unit(ra, dec)
    sc = scene(c.orbit, times)

    def at(idx):
        out, obs, door = [], [], []
        for i in idx:
            sat = np.broadcast_to(sc.satellite_km[i], los.shape)
            bodies = {k: np.broadcast_to(v[i], los.shape) for k, v in sc.bodies_km.items()}
            g = observing_geometry(sat, bodies, los, c.earth.radius_km, c.constraints)
            r = cm.evaluate(sat, bodies, los, g, bench.bands, stars)
            out.append([r[b]["total"] for b in bench.bands])
            obs.append(g["observable"])
            door.append(g["door_opening_deg"])
        return np.array(out), np.array(obs), np.array(door)  # (T, B, P), (T, P), (T, P)

    t_start = time.perf_counter()
    full, obs, door = at(range(len(times)))
    per_sample = (time.perf_counter() - t_start) / (len(times) * los.shape[0])
    rows = []
    x = np.arange(len(times))
    for step in (1, 5, 10, 30, 60):
        idx = np.arange(0, len(times), step)
        coarse = full[idx]  # the same numbers a coarse run computes
        interp = np.empty_like(full)
        for b in range(full.shape[1]):
            for p in range(full.shape[2]):
                interp[:, b, p] = np.interp(x, idx, coarse[:, b, p])
        rel = np.abs(interp - full) / full
        err = float(np.max(np.where(obs[:, None, :], rel, 0.0)))
        p99 = float(np.percentile(rel.transpose(0, 2, 1)[obs], 99))
        cost = per_sample * len(idx) / len(times)
        rows.append(
            {
                "setting": f"{step * fine_s:.0f} s",
                "max_rel_error": err,
                "p99_rel_error": p99,
                "seconds_per_sample": cost,
            }
        )
        print(
            f"  {'cadence':14s} {step * fine_s:6.0f} s{'':17s} error {err:9.2e} (p99 {p99:.1e}) "
            f"{cost * 1e3:8.3f} ms/sample"
        )
        if step == 1:
            continue
        # adaptive: drop the samples interpolation reproduces
        computed, adaptive = adaptive_in_time(full, obs, door, step, ADAPTIVE_CHECK_FRACTION)
        rel_a = np.abs(adaptive - full) / full
        err_a = float(np.max(np.where(obs[:, None, :], rel_a, 0.0)))
        fraction = float(computed.mean())
        rows.append(
            {
                "setting": f"adaptive {step * fine_s:.0f} s",
                "max_rel_error": err_a,
                "seconds_per_sample": per_sample * fraction,
                "fraction_computed": fraction,
            }
        )
        print(
            f"  {'cadence':14s} adaptive {step * fine_s:6.0f} s{'':8s} error {err_a:9.2e}   "
            f"{per_sample * fraction * 1e3:8.3f} ms/sample ({fraction:.0%} computed)"
        )
    return rows


def nside_rows(bench):
    """A pixel's value standing for every direction inside it: random directions against the
    value at their pixel's centre, at one time."""
    import healpy as hp

    from straylight.model import BackgroundModel
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    c = bench.campaign
    cm = BackgroundModel(c)
    stars = bench.stars(*DEFAULT_STARS)
    sc = scene(c.orbit, ["2026-01-01T03:00:00"])
    rng = np.random.default_rng(4)
    n = 400
    ra, dec = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))

    def total(ra_, dec_):
        los = radec_to_unit(ra_, dec_)
        sat = np.broadcast_to(sc.satellite_km[0], los.shape)
        bodies = {k: np.broadcast_to(v[0], los.shape) for k, v in sc.bodies_km.items()}
        g = observing_geometry(sat, bodies, los, c.earth.radius_km, c.constraints)
        r = cm.evaluate(sat, bodies, los, g, bench.bands, stars)
        return np.array([r[b]["total"] for b in bench.bands]), g["observable"]

    exact, obs = total(ra, dec)
    rows = []
    for nside in (8, 16, 32, 64, 128):
        pix = hp.ang2pix(nside, ra, dec, lonlat=True)
        cra, cdec = hp.pix2ang(nside, pix, lonlat=True)
        centre, obs_c = total(cra, cdec)
        both = obs & obs_c
        err = float(np.max(np.abs(centre - exact)[:, both] / exact[:, both]))
        cost_rel = hp.nside2npix(nside) / hp.nside2npix(16)
        rows.append(
            {
                "setting": f"nside {nside}",
                "max_rel_error": err,
                "cost_relative_to_nside16": cost_rel,
                "seconds_per_sample": cost_rel,
            }
        )
        print(f"  {'nside':14s} {nside:<24d} error {err:9.2e}   cost x{cost_rel:g} of nside 16")
    return rows
