"""The direct off-field stars' (sample, star) pairs (paper sect. 2.2): per HEALPix sky cell and
floor level the stars of smallest bound are left out while their bounds add up to no more than
the stars_skip budget of the sample's floor (:class:`StarCells`,
:meth:`DirectStarPairs.star_cells`); :meth:`DirectStarPairs.pairs` finds each sample's pairs
with a compiled kernel (:func:`_star_pairs_kernel`).  :class:`DirectStarPairs` is a part of
:class:`~straylight.sources.stars.OffFieldStars`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from straylight.sky.limb import earth_blocks
from straylight.sky.runs import scene_runs, tiled_period
from straylight.sources.stars_table import StarTable
from straylight.util.kernel_cache import njit

__all__ = ["DirectStarPairs", "StarCells"]


@dataclass(frozen=True)
class StarCells:
    """Candidate direct stars per HEALPix sky cell (ring order) and floor level
    (:meth:`DirectStarPairs.star_cells`): cell c's candidates at level l are
    ``stars[start[c] : start[c] + count[c, l]]`` (less those that count everywhere at l) and
    ``sky_order[:sky_count[l]]``."""

    nside: int
    stars: np.ndarray  # star indices, cell after cell
    start: np.ndarray  # (cells,) each cell's first entry
    count: np.ndarray  # (cells, levels) candidates
    sky_order: np.ndarray  # star indices, by the number of levels at which they count everywhere
    sky_count: np.ndarray  # (levels,) whole-sky candidates: a prefix of sky_order
    everywhere: np.ndarray  # (stars,) levels 0 .. everywhere - 1 count for the whole sky

    def cell_of(self, unit_vectors) -> np.ndarray:
        """The sky cell of each unit vector (N, 3).

        Parameters
        ----------
        unit_vectors : ndarray, shape (N, 3)
            ICRS unit vectors.

        Returns
        -------
        ndarray of int, shape (N,)
            HEALPix ring-order pixel indices at :attr:`nside`.
        """
        from straylight.util.healpix import healpy

        hp = healpy()

        v = np.asarray(unit_vectors, float)
        return hp.vec2pix(self.nside, v[:, 0], v[:, 1], v[:, 2])


class DirectStarPairs:
    """The direct stars' pairs of :class:`~straylight.sources.stars.OffFieldStars` (its
    ``context``: the sources' :class:`~straylight.sources.context.SourceContext`, and
    ``policy``: the fidelity policy).  The skip's knobs are class attributes (a test may set
    them)."""

    #: the star skip's floor levels, in units of the darkest zodiacal light: a sample's floor
    #: is rounded down to one of them, so each sky cell's candidates are chosen once per level
    STAR_FLOOR_LEVELS = 4.0 ** np.arange(12)

    def bound_scale(self, stars: StarTable) -> np.ndarray:
        """Per direct star, (S,), its e-/s/pix at PST = 1 (Se = Sp = 1) as a fraction of the
        darkest zodiacal light, in the band where that fraction is largest: times the PST's
        bound at a line of sight (:meth:`~straylight.optics.pst.PST.tail_max`), an upper bound of the
        star's share of any total in every band.

        Parameters
        ----------
        stars : StarTable
            The star table (its direct stars).

        Returns
        -------
        ndarray, shape (S,)
            Dimensionless ratio to the darkest zodiacal light (0 for a star in none of the
            campaign's bands).
        """
        rel = np.zeros(len(stars.ra_deg))
        for b in self.context.campaign.bands:
            if b in stars.mag_ab:
                e = self.context.photometry(b).from_ab(stars.mag_ab[b]) * self.context.offfield.pixel_area_m2
                rel = np.maximum(rel, e / self.context.darkest_zodiacal_e_per_s(b))
        return rel

    #: HEALPix nside of the sky cells whose lines of sight share a list of candidate direct
    #: stars (:meth:`star_cells`): a cell's radius (1.9 deg at 32) loosens every star's bound
    #: over the cell, so finer cells sum fewer pairs but cost more to build (the lists: once per
    #: star table); at 16, 32 and 64 a cube batch's time is the same within noise, 32 the balance
    STAR_CELL_NSIDE = 32
    #: the cells' lists hold this many entries at most (int32: 64 MB; while they are built, 16
    #: bytes an entry): beyond, the stars listed in most cells are summed at every line of
    #: sight at every level instead (a deep catalog at a tiny tolerance, where nearly every
    #: star is needed nearly everywhere)
    STAR_CELL_ENTRIES = 16_000_000
    #: candidate (sample, star) pairs tested at once: bounds the memory of a deep catalog
    STAR_PAIRS_PER_PASS = 1 << 20

    def star_cells(self, stars: StarTable) -> "StarCells":
        """Per sky cell (HEALPix ring order, :attr:`STAR_CELL_NSIDE`) and floor level
        (:attr:`STAR_FLOOR_LEVELS`), the direct stars summed at the cell's lines of sight; the
        others are skipped.  Each star's bound over the cell is its :meth:`bound_scale`
        times the PST's :meth:`~straylight.optics.pst.PST.tail_max` from its angle to the cell's
        nearest point (the angle to the centre less the cell's radius; :meth:`_cell_bound_table`):
        the stars of smallest bound are skipped for as long as their bounds add up to no more
        than the stars_skip share of the tolerance (1/8) times the level, and the rest are the
        candidates.  So at every line of sight of the cell the skipped stars together stay below
        that share of the sample's floor (a lower bound of its total) in every
        band, the Earth and the door only lowering them further.  One budget shared by all the
        stars rather than split evenly among them: a line of sight sees few stars close, so
        most stars' bounds are far below the budget and the few near ones may take it all
        (an even split would hold each star to a tiny share and sum many more pairs).  The
        smallest bounds are found
        without sorting: they are binned by :attr:`STAR_BOUND_BINS_PER_DEX` and whole bins are
        skipped, from the smallest, while their sum stays within the budget.

        Each cell's candidates are sorted by the number of levels that need them, so a level's
        candidates are a prefix of the cell's list.  A star that every cell needs at a level (a
        bright star against the darkest floors, or every star at a tiny tolerance) is listed
        once for the whole sky there instead of in every cell.  Cached on the star table.

        Parameters
        ----------
        stars : StarTable
            The star table (its direct stars).

        Returns
        -------
        StarCells
        """
        from straylight.util.healpix import healpy

        hp = healpy()

        key = (id(self), tuple(self.context.campaign.bands), self.policy.tolerance, self.STAR_CELL_NSIDE)
        cache = stars.__dict__.setdefault("_cells_cache", {})
        if key in cache:
            return cache[key]
        n_stars, n_levels = len(stars.ra_deg), self.STAR_FLOOR_LEVELS.size
        nside = self.STAR_CELL_NSIDE
        n_cells = hp.nside2npix(nside)
        centres = np.array(hp.pix2vec(nside, np.arange(n_cells))).T
        bb = self._bound_bins(stars, hp.max_pixrad(nside))
        # a star whose bound exceeds a level's budget even at the far side of the sky is summed
        # at every line of sight there: its entries below that level are never listed
        sure = np.count_nonzero(bb.rel[:, None] * bb.tail[0] > bb.budget[None, :], axis=1)
        s_unit = stars.unit if n_stars else np.zeros((0, 3))
        everywhere = np.full(n_stars, n_levels, np.intp)  # levels at which every cell needs the star
        promoted = np.zeros(n_stars, bool)  # summed everywhere at every level: the lists outgrew the cap
        parts, n_entries = [], 0
        block = max(1, (1 << 21) // max(n_stars, bb.n_bins))  # cells at a time: arrays of ~2 million
        for a in range(0, n_cells, block):
            reach = _block_reach(bb, centres[a : a + block], s_unit)
            if n_stars:
                everywhere = np.minimum(everywhere, reach.min(axis=0))
            r, k = np.nonzero((reach > sure) & ~promoted)
            parts.append((r + a, k, reach[r, k]))
            n_entries += r.size
            if n_entries > self.STAR_CELL_ENTRIES:
                parts = self._promote_to_whole_sky(parts, promoted, self.STAR_CELL_ENTRIES // 2)
                n_entries = sum(p[0].size for p in parts)
        everywhere[promoted] = n_levels
        cells = _cells_from_entries(parts, everywhere, n_cells, n_levels, nside)
        cache[key] = cells
        return cells

    def _bound_bins(self, stars: StarTable, max_pixrad_rad: float) -> _BoundBins:
        """:meth:`star_cells`' bounds and their bins, for cells of largest centre-to-corner
        distance ``max_pixrad_rad``."""
        rel = self.bound_scale(stars)
        # a hair under the share, against the rounding of the sums
        budget = self.policy.budget("stars_skip") * self.STAR_FLOOR_LEVELS * (1.0 - 1e-9)
        # max_pixrad: the largest centre-to-corner distance; 1 % and 1e-9 rad over it for the
        # curved edges and rounding (sampled: no point of a cell lies beyond 0.999 of it)
        tail = self._cell_bound_table(1.01 * max_pixrad_rad + 1e-9)
        per_cos = (tail.size - 1) / 2.0
        # bins from STAR_BOUND_DEPTH_DEX below the smallest budget (the first bin gathers every
        # smaller bound) to a dex over the largest (the last holds bounds no level skips)
        per_dex = self.STAR_BOUND_BINS_PER_DEX
        lo_dex = int(np.floor(np.log10(budget[0]))) - self.STAR_BOUND_DEPTH_DEX
        n_bins = (int(np.ceil(np.log10(budget[-1]))) + 1 - lo_dex) * per_dex + 1
        with np.errstate(divide="ignore"):
            log_rel, log_tail = np.log10(rel), np.log10(tail)
        return _BoundBins(rel, log_rel, tail, log_tail, per_cos, budget, per_dex, lo_dex, n_bins)

    #: :meth:`star_cells`' bounds: the cosine nodes of its PST table, and the bins (per dex,
    #: from this many dex below the smallest budget) whose sums decide which stars are skipped.
    #: Coarser bins skip fewer stars (whole bins only): at 25 per dex (10 % wide) the default
    #: catalog's cells list a few per cent more entries than sorting every bound would, and build
    #: far faster
    STAR_BOUND_COS_NODES = 2_000_001
    STAR_BOUND_BINS_PER_DEX = 25
    STAR_BOUND_DEPTH_DEX = 8

    def _cell_bound_table(self, margin_rad: float) -> np.ndarray:
        """The PST's :meth:`~straylight.optics.pst.PST.tail_max` from ``margin_rad`` short of the angle
        whose cosine is each of :attr:`STAR_BOUND_COS_NODES` evenly spaced nodes from -1 to 1: at
        a cosine, the node at or above it (a smaller angle) bounds the tail maximum there.
        Cached per margin."""
        cache = self.__dict__.setdefault("_cell_bound_tables", {})
        if margin_rad not in cache:
            cos_nodes = np.linspace(-1.0, 1.0, self.STAR_BOUND_COS_NODES)
            angle_deg = np.degrees(np.maximum(np.arccos(cos_nodes) - margin_rad, 0.0))
            cache[margin_rad] = self.context.offfield.pst.tail_max(angle_deg)
        return cache[margin_rad]

    @staticmethod
    def _promote_to_whole_sky(parts, promoted, entries_max) -> list:
        """:meth:`star_cells`' lists so far, ``parts`` [(cell, star, reach)], less the entries
        of the stars listed in most cells, marked in ``promoted`` (in place), until at most
        ``entries_max`` entries are left: a promoted star is summed at every line of sight at
        every level (summing a star never breaks the budget; it only costs).  A deep catalog at
        a tiny tolerance (the benchmark's reference: every star needed nearly everywhere)."""
        star = np.concatenate([p[1] for p in parts])
        entries = np.bincount(star, minlength=promoted.size)
        entries[promoted] = 0
        by_entries = np.argsort(-entries, kind="stable")
        excess = entries.sum() - entries_max
        if excess > 0:
            promoted[by_entries[: int(np.searchsorted(np.cumsum(entries[by_entries]), excess)) + 1]] = True
        return [(c[~promoted[k]], k[~promoted[k]], r[~promoted[k]]) for c, k, r in parts]

    def pairs(self, stars: StarTable, frame, sat, door, floor_ratio=1.0, runs=None):
        """The off-field catalog stars' band-independent transfer, E = 1 photon s-1 m-2:
        Se * Sp * PST * pixel factor, for the (sample, star) pairs that count: the star is a
        candidate of the sample's sky cell at its floor level (``floor_ratio`` >= 1 times the
        darkest zodiacal light, per sample; :meth:`star_cells`), is not behind the Earth, and is
        outside the field (stars inside scatter and make ghosts instead).  Returns the shape of
        the samples and ``(sample, star, transfer)``: flat sample index, star index, transfer.

        Where samples come in runs that share a satellite position (cube time steps) the Earth
        test runs once per star and step (``runs``: the samples' scene runs when known).

        Parameters
        ----------
        stars : StarTable
            The star table (its direct stars).
        frame : TelescopeFrame
            The samples' telescope frames, axes (..., 3).
        sat : ndarray, shape (..., 3)
            Geocentric ICRS satellite positions, km.
        door : array_like
            Each sample's door opening, deg.
        floor_ratio : float or array_like
            Each sample's floor over the darkest zodiacal light, >= 1.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        shape : tuple
            The samples' broadcast shape.
        pairs : tuple of (ndarray, ndarray, ndarray), each shape (P,)
            Flat sample index (int), star index (int) and transfer (e-/s/pix per photon s-1 m-2
            of the star at the aperture).
        """
        s_all = np.ascontiguousarray(stars.unit, dtype=float)  # (S, 3)
        cells = self.star_cells(stars)
        shape = np.broadcast_shapes(np.shape(frame.z)[:-1], np.shape(door), np.shape(sat)[:-1])
        fz, fx, fy = (
            np.ascontiguousarray(np.broadcast_to(a, shape + (3,)).reshape(-1, 3), dtype=float)
            for a in (frame.z, frame.x, frame.y)
        )
        op = np.broadcast_to(np.asarray(door, float), shape).ravel()
        level = self._floor_level(floor_ratio, shape)
        re_km = self.context.campaign.earth.radius_km
        sat_b = np.broadcast_to(np.asarray(sat, float), shape + (3,))
        runs = scene_runs(sat_b, runs=runs)
        period = tiled_period(fz, runs)  # a cube batch: the same lines of sight at every time step
        earth = self._earth_test(runs, s_all, sat_b, re_km)
        cell = cells.cell_of(fz) if period is None else np.tile(cells.cell_of(fz[:period]), len(fz) // period)
        n_cand = (
            cells.count[cell, level] + cells.sky_count[level]
        )  # the cell's and the whole sky's candidates
        ends = np.cumsum(n_cand)
        parts = []
        a = 0
        while a < fz.shape[0]:  # passes of at most STAR_PAIRS_PER_PASS candidates (one sample at least)
            base = ends[a - 1] if a else 0
            b = max(int(np.searchsorted(ends, base + self.STAR_PAIRS_PER_PASS, side="right")), a + 1)
            span = (a, b, int(ends[b - 1] - base))
            parts.append(self._pass_pairs(span, (fz, fx, fy), s_all, (level, cell, cells), earth, op))
            a = b
        if not parts:
            return shape, (np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0))
        return shape, tuple(np.concatenate(x) for x in zip(*parts))

    def _floor_level(self, floor_ratio, shape) -> np.ndarray:
        """Each sample's floor level (index into :attr:`STAR_FLOOR_LEVELS`), flat: rounded down,
        so its budget is never too large."""
        level = (
            np.searchsorted(
                self.STAR_FLOOR_LEVELS,
                np.broadcast_to(np.asarray(floor_ratio, float), shape).ravel(),
                side="right",
            )
            - 1
        )
        return np.clip(level, 0, self.STAR_FLOOR_LEVELS.size - 1)

    def _earth_test(self, runs, s_all, sat_b, re_km) -> tuple:
        """What the pairs' kernel tests the Earth with: (star_blocked (R, S), run_index,
        sat_flat (N, 3) km), once per star and scene run, or (empty, empty, the samples'
        satellites) to test per pair."""
        if runs is not None and runs.count * len(s_all) > self.STAR_PAIRS_PER_PASS:
            runs = None  # many short runs of a deep catalog: the test per pair costs less memory
        if runs is not None:  # the Earth test once per star and time step
            star_blocked = earth_blocks(runs.vectors[0][:, None, :], s_all[None], re_km)  # (R, S)
            return star_blocked, runs.index, np.zeros((0, 3))
        return np.zeros((0, 0), bool), np.zeros(0, np.intp), np.ascontiguousarray(sat_b.reshape(-1, 3))

    def _pass_pairs(self, span, los, s_all, where, earth, op) -> tuple:
        """One pass of :meth:`pairs`: samples ``span`` = (first, end, candidates) with their
        frames ``los`` (z, x, y), the stars ``s_all``, ``where`` (level, cell, cells) and
        ``earth`` (:meth:`_earth_test`); (sample, star, transfer)."""
        a, b, n_pairs = span
        fz, fx, fy = los
        level, cell, cells = where
        star_blocked, run_index, sat_flat = earth
        r, k, theta, phi = (np.empty(n_pairs, t) for t in (np.intp, np.intp, float, float))
        n = _star_pairs_kernel(
            a,
            b,
            fz,
            fx,
            fy,
            s_all,
            level,
            cell,
            cells.start,
            cells.count,
            cells.stars,
            cells.sky_order,
            cells.sky_count,
            cells.everywhere,
            star_blocked,
            run_index,
            sat_flat,
            float(self.context.campaign.earth.radius_km),
            float(self.context.offfield.field_radius_deg),
            r,
            k,
            theta,
            phi,
        )
        r, k, theta, phi = r[:n], k[:n], theta[:n], phi[:n]
        return r, k, self.context.offfield.point_source(1.0, theta, phi, False, op[r])


class _BoundBins(NamedTuple):
    """:meth:`DirectStarPairs.star_cells`' bounds: each star's bound scale (``rel``) and the PST
    table from the cell's nearest point (``tail``, over :attr:`STAR_BOUND_COS_NODES` cosines,
    ``per_cos`` nodes per unit cosine), their log10, the budget per floor level, and the bins
    (``per_dex`` per dex from ``lo_dex``, ``n_bins`` in all)."""

    rel: np.ndarray
    log_rel: np.ndarray
    tail: np.ndarray
    log_tail: np.ndarray
    per_cos: float
    budget: np.ndarray
    per_dex: int
    lo_dex: int
    n_bins: int


def _block_reach(bb: _BoundBins, centres: np.ndarray, s_unit: np.ndarray) -> np.ndarray:
    """(cells, stars): the number of floor levels (from the lowest) that need each star at each
    of the cells of unit ``centres`` (c, 3): at a level, the stars of the leading bins whose sum
    stays within its budget are skipped."""
    n_bins, per_dex, lo_dex = bb.n_bins, bb.per_dex, bb.lo_dex
    node = np.clip(np.ceil((centres @ s_unit.T + 1.0) * bb.per_cos), 0, bb.tail.size - 1).astype(np.intp)
    bound = bb.rel * bb.tail[node]  # (c, S)
    bins = np.clip(
        np.floor((bb.log_rel + bb.log_tail[node]) * per_dex) - lo_dex * per_dex, 0, n_bins - 1
    ).astype(np.intp)
    rows = bins.shape[0]
    sums = np.bincount(
        (np.arange(rows)[:, None] * n_bins + bins).ravel(),
        weights=bound.ravel(),
        minlength=rows * n_bins,
    ).reshape(rows, n_bins)
    cum = np.cumsum(sums, axis=1)
    # per level, the leading bins skipped; per bin, the levels that skip it not: a star's
    # reach (the levels that need it, nested: 0 .. reach - 1) is its bin's
    cut = np.stack([np.count_nonzero(cum <= lim, axis=1) for lim in bb.budget], axis=1)  # (c, L)
    reach_of_bin = np.cumsum(
        np.bincount(
            (np.arange(rows)[:, None] * (n_bins + 1) + cut).ravel(), minlength=rows * (n_bins + 1)
        ).reshape(rows, -1),
        axis=1,
    )
    return np.take_along_axis(reach_of_bin, bins, axis=1)


def _cells_from_entries(parts, everywhere, n_cells: int, n_levels: int, nside: int) -> StarCells:
    """:class:`StarCells` from the entries ``parts`` [(cell, star, reach)] and each star's levels
    at which every cell needs it (``everywhere``)."""
    cell, star, reach = (np.concatenate(x) for x in zip(*parts))
    kept = reach > everywhere[star]  # entries the whole sky's list does not already hold
    cell, star, reach = cell[kept], star[kept], reach[kept]
    order = np.lexsort((-reach, cell))  # cell after cell, each by decreasing reach
    cell, star, reach = cell[order], star[order], reach[order]
    hist = np.bincount(cell * (n_levels + 1) + reach, minlength=n_cells * (n_levels + 1)).reshape(n_cells, -1)
    counts = np.cumsum(hist[:, ::-1], axis=1)[:, ::-1][:, 1:]  # (cells, levels): reach > level
    start = np.concatenate([[0], np.cumsum(counts[:, 0])[:-1]]).astype(np.intp)
    sky_order = np.argsort(-everywhere, kind="stable")
    sky_count = np.array([np.count_nonzero(everywhere > lv) for lv in range(n_levels)], np.intp)
    return StarCells(nside, star.astype(np.int32), start, counts, sky_order, sky_count, everywhere)


@njit(cache=True, nogil=True)
def _star_pairs_kernel(
    first,
    stop,
    fz,
    fx,
    fy,
    s,
    level,
    cell,
    start,
    count,
    cell_stars,
    sky_order,
    sky_count,
    everywhere,
    blocked_by_run,
    run_index,
    sat,
    re_km,
    field_radius_deg,
    out_sample,
    out_star,
    out_theta,
    out_phi,
):
    """:meth:`OffFieldStars.pairs` for samples ``first`` .. ``stop`` - 1: each sample's
    candidates (its sky cell's at its level, then the whole sky's), kept where the star is
    not behind the Earth (per run from ``blocked_by_run``, else tested
    here against ``sat``) and lies outside the field; writes (sample, star, theta, phi) of the
    pairs kept and returns their number.  One pass per candidate instead of numpy's pass per
    operation over every candidate."""
    n = 0
    for i in range(first, stop):
        lv = level[i]
        c = cell[i]
        n_cell = count[c, lv]
        for j in range(n_cell + sky_count[lv]):
            if j < n_cell:
                k = cell_stars[start[c] + j]
                if everywhere[k] > lv:  # a whole-sky star at this level: the sky's list has it
                    continue
            else:
                k = sky_order[j - n_cell]
            if blocked_by_run.size:
                if blocked_by_run[run_index[i], k]:
                    continue
            else:  # geometry.earth_blocks: behind the satellite's horizon plane and within the Earth
                sk = np.sqrt(s[k, 0] ** 2 + s[k, 1] ** 2 + s[k, 2] ** 2)
                u0, u1, u2 = s[k, 0] / sk, s[k, 1] / sk, s[k, 2] / sk
                x0, x1, x2 = sat[i, 0], sat[i, 1], sat[i, 2]
                if u0 * x0 + u1 * x1 + u2 * x2 < 0.0:
                    m0, m1, m2 = x1 * u2 - x2 * u1, x2 * u0 - x0 * u2, x0 * u1 - x1 * u0
                    if np.sqrt(m0 * m0 + m1 * m1 + m2 * m2) < re_km:
                        continue
            dz = fz[i, 0] * s[k, 0] + fz[i, 1] * s[k, 1] + fz[i, 2] * s[k, 2]
            dx = fx[i, 0] * s[k, 0] + fx[i, 1] * s[k, 1] + fx[i, 2] * s[k, 2]
            dy = fy[i, 0] * s[k, 0] + fy[i, 1] * s[k, 1] + fy[i, 2] * s[k, 2]
            theta = np.degrees(np.arctan2(np.hypot(dx, dy), dz))
            if not theta > field_radius_deg:
                continue
            phi = np.degrees(np.arctan2(dy, dx))
            out_sample[n] = i
            out_star[n] = k
            out_theta[n] = theta
            out_phi[n] = phi + 360.0 if phi < 0.0 else phi
            n += 1
    return n
