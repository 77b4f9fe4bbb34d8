"""The fast grid interpolator against scipy's RegularGridInterpolator (the independent library)."""

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from straylight.util.gridinterp import LinearGrid


@pytest.mark.parametrize("ndim", [2, 3, 4])
def test_matches_scipy_on_nonuniform_axes(ndim):
    rng = np.random.default_rng(1)
    # non-uniform axes with a narrow cell among wide ones (like the PST's anchor nodes)
    axes = [
        np.unique(np.concatenate([np.linspace(0, 180, 19), [30.01, 30.02, 0.5], rng.uniform(0, 180, 5)]))
        for _ in range(ndim)
    ]
    values = rng.normal(size=tuple(a.size for a in axes))
    pts = rng.uniform(0, 180, size=(200_000, ndim))
    pts[:50] = np.array(np.meshgrid(*axes, indexing="ij")).reshape(ndim, -1).T[:50]  # exactly on nodes
    pts[50:60] = 180.0  # upper edge
    pts[60:70] = 0.0
    ref = RegularGridInterpolator(axes, values, method="linear")(pts)
    got = LinearGrid(axes, values)(*pts.T)
    assert np.max(np.abs(got - ref)) < 1e-12


@pytest.mark.parametrize("ndim", [1, 2, 3])
def test_uniform_axes_match_scipy_at_and_beside_nodes(ndim):
    """Evenly spaced axes take the one-multiplication cell finder: the same values as scipy at
    random points, on every node, one rounding step either side of it (where the cell found may
    be the neighbouring one, with t ~1 or ~0), at the edges, outside (clipped) and at NaN; and
    the general finder's values to rounding (it runs on a copy told the axes are uneven)."""
    rng = np.random.default_rng(4)
    axes = [np.linspace(0.0, 360.0, 73), np.linspace(0.0, 90.0, 91), np.linspace(-1.5, 2.5, 9)][:ndim]
    values = rng.normal(size=tuple(a.size for a in axes))
    nodes = np.array(np.meshgrid(*axes, indexing="ij")).reshape(ndim, -1).T
    pts = np.concatenate(
        [
            rng.uniform(-10.0, 370.0, size=(50_000, ndim)),
            nodes,
            np.nextafter(nodes, np.inf),
            np.nextafter(nodes, -np.inf),
        ]
    )
    lo, hi = np.array([a[0] for a in axes]), np.array([a[-1] for a in axes])
    grid = LinearGrid(axes, values)
    assert all(ax.uniform for ax in grid.axes)
    ref = RegularGridInterpolator(axes, values, method="linear")(np.clip(pts, lo, hi))
    got = grid(*pts.T)
    assert np.max(np.abs(got - ref)) < 1e-12
    general = LinearGrid(axes, values)
    for ax in general.axes:
        ax.uniform = False
    assert np.max(np.abs(got - general(*pts.T))) < 1e-13
    assert np.isnan(grid(*([np.nan] + [1.0] * (ndim - 1))))


def test_clips_outside_and_propagates_nan():
    f = LinearGrid(
        [np.array([0.0, 1.0, 3.0]), np.array([0.0, 2.0])], np.array([[0.0, 2.0], [1.0, 3.0], [3.0, 5.0]])
    )
    assert f(-5.0, 1.0) == pytest.approx(1.0)  # clipped to x = 0: 0 + (2 - 0) * 1/2
    assert f(10.0, 2.0) == pytest.approx(5.0)
    assert f(2.0, 1.0) == pytest.approx(3.0)  # (2 + 4) / 2
    assert np.isnan(f(np.nan, 1.0)) and np.isnan(f(1.0, np.nan))


def test_rejects_bad_axes():
    with pytest.raises(ValueError):
        LinearGrid([np.array([0.0, 0.0, 1.0])], np.zeros(3))
    with pytest.raises(ValueError):
        LinearGrid([np.array([0.0, 1.0])], np.zeros(3))


@pytest.mark.parametrize("ndim", [2, 4])
def test_channels_match_scipy_per_channel(ndim):
    """Values with a trailing dimension (the look-up tables' direct and door terms on one grid)
    give, per channel, what scipy gives for that channel alone."""
    rng = np.random.default_rng(2)
    axes = [np.unique(np.r_[np.linspace(0.0, 90.0, 7), rng.uniform(0, 90, 3)]) for _ in range(ndim)]
    values = rng.normal(size=tuple(a.size for a in axes) + (2,))
    pts = rng.uniform(-5.0, 95.0, size=(20_000, ndim))  # some outside: clipped
    got = LinearGrid(axes, values)(*pts.T)
    assert got.shape == (20_000, 2)
    for c in range(2):
        ref = RegularGridInterpolator(axes, values[..., c], method="linear")(np.clip(pts, 0.0, 90.0))
        assert np.max(np.abs(got[:, c] - ref)) < 1e-12


def test_channel_picks_each_points_own_table_with_the_same_numbers():
    """channel=: each point's own channel (or group of channels) of a stacked grid, bit for bit
    what that channel's own grid gives (the door states' Sp tables, and the earthshine tables'
    direct and door terms per state, located once for a batch with mixed states)."""
    rng = np.random.default_rng(3)
    axes = [np.unique(np.r_[np.linspace(0.0, 90.0, 10), 33.3]), np.linspace(0.0, 360.0, 13)]
    values = rng.uniform(size=(axes[0].size, axes[1].size, 4))
    pts = rng.uniform(-5.0, 365.0, size=(5000, 2))
    ch = rng.integers(0, 4, 5000)
    got = LinearGrid(axes, values)(*pts.T, channel=ch)
    for c in range(4):
        own = LinearGrid(axes, values[..., c])(*pts[ch == c].T)
        assert np.array_equal(got[ch == c], own)
    with pytest.raises(ValueError, match="channel outside"):
        LinearGrid(axes, values)(*pts.T, channel=4)
    with pytest.raises(ValueError, match="one trailing dimension"):
        LinearGrid(axes, values[..., 0])(*pts.T, channel=0)
    # groups of channels (the earthshine tables: each door state's direct and door terms) on
    # three axes: each point's own pair, bit for bit what that pair's own grid gives
    axes3 = axes + [np.array([0.0, 1.0, 3.0])]
    values3 = rng.uniform(size=(axes[0].size, axes[1].size, 3, 6))
    pts3 = np.c_[pts, rng.uniform(-0.5, 3.5, 5000)]
    group = rng.integers(0, 3, 5000)
    got = LinearGrid(axes3, values3)(*pts3.T, channel=group, group=2)
    assert got.shape == (5000, 2)
    for g in range(3):
        own = LinearGrid(axes3, values3[..., 2 * g : 2 * g + 2])(*pts3[group == g].T)
        assert np.array_equal(got[group == g], own)
    with pytest.raises(ValueError, match="in groups of 4"):
        LinearGrid(axes3, values3)(*pts3.T, channel=group, group=4)
    with pytest.raises(ValueError, match="channel outside"):
        LinearGrid(axes3, values3)(*pts3.T, channel=3, group=2)


@pytest.mark.parametrize("ndim", [2, 3, 4, 5])
def test_group_major_storage_gives_the_same_values(ndim):
    """LinearGrid(channel_group=g) stores the table group-major (each point's cell corners hold
    only its own group's channels): bit for bit the values of the node-major grid read with the
    same channel groups, which match scipy per channel; NaN and out-of-range points included.
    Read without its groups, it refuses."""
    rng = np.random.default_rng(5)
    axes = [np.unique(np.concatenate([np.linspace(0, 180, 7), rng.uniform(0, 180, 3)])) for _ in range(ndim)]
    values = rng.normal(size=tuple(a.size for a in axes) + (6,))  # three groups of two channels
    pts = rng.uniform(-5.0, 185.0, size=(5000, ndim))
    pts[:3, 0] = np.nan
    channel = rng.integers(0, 3, 5000)
    node_major = LinearGrid(axes, values)(*pts.T, channel=channel, group=2)
    grouped = LinearGrid(axes, values, channel_group=2)
    got = grouped(*pts.T, channel=channel, group=2)
    np.testing.assert_array_equal(got, node_major)
    assert np.isnan(got[:3]).all()
    clipped = np.clip(pts[3:], 0.0, 180.0)
    for j in range(2):
        ref = RegularGridInterpolator(axes, values[..., j::2], method="linear")(clipped)[
            np.arange(4997), channel[3:]
        ]
        assert np.max(np.abs(got[3:, j] - ref)) < 1e-12
    with pytest.raises(ValueError, match="groups of 2"):
        grouped(*pts.T)
    with pytest.raises(ValueError, match="needs one trailing dimension"):
        LinearGrid(axes, values[..., :5], channel_group=2)
