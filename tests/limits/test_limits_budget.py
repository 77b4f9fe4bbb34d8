"""The depth error budget (straylight.limits.budget): its ranges against their sources, its
interval against an independent CCD equation, the worst-hour percentiles, and the products."""

import numpy as np
import pytest

SNR = 5.0
EE = 0.8


def _ccd_limit(sky, t_total, n_exp, read_noise, dark, r80_arcsec, pix_arcsec, zp_e_per_s):
    """The 5-sigma limit of the CCD equation written out here (not the library's): S = 5 sigma,
    sigma^2 = S + N_pix (B T + D T + n RN^2), S = 0.8 F T."""
    n_pix = np.pi * (r80_arcsec / pix_arcsec) ** 2
    nb = n_pix * (sky * t_total + dark * t_total + n_exp * read_noise**2)
    s = (SNR**2 + np.sqrt(SNR**4 + 4 * SNR**2 * nb)) / 2
    return -2.5 * np.log10(s / (EE * t_total * zp_e_per_s))


def _pole_zodiacal(campaign, spectrum):
    """Each band's zodiacal light at the ecliptic pole with the colour law ``spectrum``, e-/s/pix."""
    from straylight.optics.bandpass import load_band
    from straylight.sources.zodiacal import icrs_to_ecliptic_matrix, zodiacal_model_from_instrument

    models = campaign.settings.models
    zm = zodiacal_model_from_instrument(
        campaign.instrument_settings, spectrum, models.zodiacal_reddening.as_tuple()
    )
    pole = icrs_to_ecliptic_matrix().T @ np.array([0.0, 0.0, 1.0])
    out = {}
    for b in campaign.bands:
        band = load_band(campaign.instrument_settings, b, campaign.instrument_path.parent)
        out[b] = float(np.ravel(zm.evaluate(band, pole, np.array([1.0, 0.0, 0.0]))["e_per_s_per_pix"])[0])
    return out


def test_zodiacal_ranges_are_the_spread_of_the_colour_laws_carried(campaign):
    """depth_budget.zodiacal_level per band: [min, max] of 1 and the rates of `solar_leinert` and
    `hst` over the default `leinert_fit` at the ecliptic pole (docs/assumptions.md, Zodiacal
    colours: NUV up to 1.587, u 1.205, g 1.065, r 0.969-1.066, i 0.937-1.122, z 0.933-1.145,
    y 0.975-1.156), within 1 %."""
    default = campaign.settings.models.zodiacal_spectrum
    base = _pole_zodiacal(campaign, default)
    others = [_pole_zodiacal(campaign, s) for s in ("solar_leinert", "hst") if s != default]
    spec = campaign.instrument_settings.depth_budget.zodiacal_level
    for b in campaign.bands:
        ratios = [1.0] + [o[b] / base[b] for o in others]
        lo, hi = spec[b].range
        print(b, [round(r, 3) for r in ratios], (lo, hi))
        assert lo == pytest.approx(min(ratios), rel=0.01), b
        assert hi == pytest.approx(max(ratios), rel=0.01), b


def test_read_noise_alone_moves_the_darkest_sky_depth_as_the_ccd_equation(campaign):
    """The budget's read-noise term at 4 and 6 e- moves g's limit at the darkest sky (0.060
    e-/s/pix, the ecliptic pole's zodiacal light) as the CCD equation written out here: by
    +0.138 / -0.131 mag (the independent review's +/-0.12-0.19 in g, r, i)."""
    from straylight.limits.budget import depth_budget, term_limits
    from straylight.limits.point_source import campaign_exposures

    bands = tuple(campaign.bands)
    terms = {t.key: t for t in depth_budget(campaign, bands)}
    ib = bands.index("g")
    x = campaign_exposures(campaign, bands)[ib]
    sky = np.full((1, len(bands)), 0.060)
    nominal = _ccd_limit(
        0.060, x.total_s, x.n_exposures, 5.0, 0.02, 0.15, campaign.pixel_scale_arcsec, x.zero_point_e_per_s
    )
    ex = campaign_exposures(campaign, bands)
    for end, rn in ((0, 4.0), (1, 6.0)):
        got = term_limits(terms["read_noise_e"], end, sky, {}, ex)[0, ib]
        want = _ccd_limit(
            0.060, x.total_s, x.n_exposures, rn, 0.02, 0.15, campaign.pixel_scale_arcsec, x.zero_point_e_per_s
        )
        print(f"read noise {rn} e-: {got - nominal:+.3f} mag")
        assert got == pytest.approx(want, abs=1e-6)
        assert abs(got - nominal) > 0.1


def _region(campaign, seed=3):
    rng = np.random.default_rng(seed)
    shape = (40, 6, len(campaign.bands))
    region = {k: rng.uniform(0.0, 0.3, shape) for k in ("zodiacal", "sun", "moon", "planets", "stars")}
    direct, door = rng.uniform(0.0, 0.5, shape), rng.uniform(0.0, 0.2, shape)
    region.update(earthshine=direct + door, earthshine_door=door)
    region["total"] = sum(region[k] for k in ("zodiacal", "sun", "moon", "planets", "stars", "earthshine"))
    region["observable"] = rng.uniform(size=shape[:2]) < 0.7
    # the envelope members' re-evaluated groups at each end (what the cube's workers compute)
    for end, scale in (("optimistic", (0.3, 1.0)), ("pessimistic", (1.0, 4.0))):
        region[f"earthshine_{end}"] = region["earthshine"] * rng.uniform(*scale, shape)
        region[f"sun_moon_{end}"] = (region["sun"] + region["moon"]) * rng.uniform(*scale, shape)
    return region


def test_budget_interval_is_the_quadrature_of_each_input_alone(campaign):
    """At each observable sample, p16 (p84) is the nominal limit minus (plus) the quadrature sum of
    the changes towards shallower (deeper) limits of each input alone at each end, each change
    computed here from the CCD equation (read noise, dark current, EE80 radius) or the scaled
    parts (zodiacal light, Moon, stars) and the envelope's ends; NaN where not observable."""
    from straylight.limits.budget import budget_limits, depth_budget
    from straylight.limits.point_source import campaign_exposures
    from straylight.model.envelope import campaign_envelope

    bands = tuple(campaign.bands)
    region = _region(campaign)
    obs = region["observable"]
    ex = campaign_exposures(campaign, bands)
    out = budget_limits(depth_budget(campaign, bands), region, ex)
    p16, p84 = out["limiting_mag_p16"], out["limiting_mag_p84"]
    assert np.all(np.isnan(p16[~obs])) and np.all(np.isfinite(p16[obs]))
    pix = campaign.pixel_scale_arcsec
    spec = campaign.instrument_settings.depth_budget
    env = campaign_envelope(campaign, bands)
    for ib, b in enumerate(bands):
        x = ex[ib]
        tot = region["total"][..., ib][obs]

        def lim(sky=tot, rn=5.0, dark=0.02, r80=0.15, zp=0.0):
            return (
                _ccd_limit(
                    sky * 10 ** (0.4 * zp), x.total_s, x.n_exposures, rn, dark, r80, pix, x.zero_point_e_per_s
                )
                + zp
            )

        m0 = lim()
        changes = []
        for rn in spec.read_noise_e.range:
            changes.append(lim(rn=rn) - m0)
        for dark in spec.dark_current_e_per_s.range:
            changes.append(lim(dark=dark) - m0)
        for r80 in spec.ee80_radius_arcsec[b].range:
            changes.append(lim(r80=r80) - m0)
        for key, leaf in (
            ("zodiacal_level", "zodiacal"),
            ("moon_level", "moon"),
            ("stars_pst_core", "stars"),
        ):
            r = getattr(spec, key)
            r = r[b] if isinstance(r, dict) else r
            for f in r.range:
                changes.append(lim(sky=tot + region[leaf][..., ib][obs] * (f - 1)) - m0)
        direct = region["earthshine"] - region["earthshine_door"]
        parts = {"earthshine_direct": direct, "earthshine_door": region["earthshine_door"]}
        parts.update({k: region[k] for k in ("sun", "moon")})
        for p in env.parameters:
            if p.reevaluated:  # the members: the end's re-evaluated groups replace the parts
                for end in ("optimistic", "pessimistic"):
                    sky = tot + sum(
                        (
                            region[f"{g}_{end}"] - region[g]
                            if g == "earthshine"
                            else region[f"{g}_{end}"] - parts["sun"] - parts["moon"]
                        )[..., ib][obs]
                        for g in ("earthshine", "sun_moon")
                    )
                    changes.append(lim(sky=sky) - m0)
                continue
            for f in (p.dark, p.bright):
                if p.zero_point:
                    changes.append(lim(zp=f[ib]) - m0)
                else:
                    sky = tot + sum(parts[leaf][..., ib][obs] * (f[ib] - 1) for leaf in p.leaves)
                    changes.append(lim(sky=sky) - m0)
        changes = np.array(changes)
        want16 = m0 - np.sqrt((np.minimum(changes, 0) ** 2).sum(axis=0))
        want84 = m0 + np.sqrt((np.maximum(changes, 0) ** 2).sum(axis=0))
        np.testing.assert_allclose(p16[..., ib][obs], want16, atol=2e-5)
        np.testing.assert_allclose(p84[..., ib][obs], want84, atol=2e-5)
        # the read noise alone moves the darkest samples by > 0.1 mag: the interval is not the
        # envelope's few millimag
        assert np.median(want84 - want16) > 0.2, b


def test_shift_percentiles_are_of_the_changes_size():
    """Per pixel, p90 / p99 is the change whose size 10 % / 1 % of the observable times exceed,
    with its sign: on 1,000 changes -0.000, -0.001, ..., -0.999 mag, p90 = -0.899 and p99 = -0.989
    (numpy's linear percentile); unobservable times are left out, a never-observable pixel NaN."""
    from straylight.limits.budget import shift_percentiles

    n = 1000
    nominal = np.full((n + 5, 2, 1), 25.0)
    pess = nominal.copy()
    pess[:n, 0, 0] = 25.0 - np.arange(n) / 1000.0
    pess[n:, 0, 0] = 10.0  # not observable: must not count
    observable = np.zeros((n + 5, 2), bool)
    observable[:n, 0] = True
    out = shift_percentiles(pess, nominal, observable)
    assert out["limiting_mag_shift_p90"][0, 0] == pytest.approx(-0.8991, abs=1e-4)
    assert out["limiting_mag_shift_p99"][0, 0] == pytest.approx(-0.98901, abs=1e-4)
    assert np.isnan(out["limiting_mag_shift_p90"][1, 0])


def test_limits_dataset_carries_the_budget_with_units(campaign):
    """limits_dataset on a small background: limiting_mag_median_p16 <= limiting_mag_median <=
    limiting_mag_median_p84 wherever observable, the shift percentiles <= 0 and p99 <= p90, each
    with units and a long_name; the existing variables are those computed without the budget."""
    import pandas as pd
    import xarray as xr

    from straylight.limits.cube import limits_dataset

    region = _region(campaign, seed=5)
    nt, npix, nb = region["total"].shape
    dims = ("time", "pixel", "band")
    ds = xr.Dataset(
        {k: (dims, np.asarray(v, np.float32)) for k, v in region.items() if k != "observable"}
        | {"observable": (("time", "pixel"), region["observable"])},
        coords={
            "time": pd.date_range("2026-01-01", periods=nt, freq="5min"),
            "pixel": np.arange(npix),
            "ra_deg": ("pixel", np.linspace(0, 50, npix)),
            "dec_deg": ("pixel", np.linspace(-10, 10, npix)),
            "band": list(campaign.bands),
        },
        attrs={"healpix_nside": 4, "healpix_ordering": "NESTED", "healpix_frame": "ICRS", "campaign": "t"},
    )
    out = limits_dataset(campaign, ds)
    without = limits_dataset(campaign, ds, budget_limits={})
    for name in ("limiting_mag_median", "limiting_mag_median_pessimistic", "limiting_mag_best"):
        np.testing.assert_array_equal(out[name].values, without[name].values)
    med = out["limiting_mag_median"].values
    lo, hi = out["limiting_mag_median_p16"].values, out["limiting_mag_median_p84"].values
    seen = np.isfinite(med)
    assert seen.any()
    assert np.all(lo[seen] < med[seen]) and np.all(med[seen] < hi[seen])
    p90, p99 = out["limiting_mag_shift_p90"].values, out["limiting_mag_shift_p99"].values
    assert np.all(p90[seen] <= 0) and np.all(p99[seen] <= p90[seen])
    for name in (
        "limiting_mag_median_p16",
        "limiting_mag_median_p84",
        "limiting_mag_shift_p90",
        "limiting_mag_shift_p99",
    ):
        assert out[name].attrs["units"] and len(out[name].attrs["long_name"]) > 20, name
