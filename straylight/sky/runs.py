"""Runs of samples that share a scene: consecutive samples with the same satellite and body
positions (a survey cube's time step over its pixels), so that what depends on the scene alone
is computed once per run and read per sample.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from straylight.util.kernel_cache import njit

__all__ = ["SceneRuns", "rows_at", "scene_rows", "scene_runs", "shared_vectors", "tiled_period"]


@dataclass(frozen=True)
class SceneRuns:
    """Samples grouped into runs of consecutive samples that share a scene (the same 3-vectors):
    ``vectors``, each (R, 3), once per run; ``index``, (N,), each flattened sample's run;
    ``shape``, the samples' shape; ``starts``, (R,), each run's first flattened sample.

    A caller that knows its samples' runs (a cube region: one per time step, :meth:`steps`)
    passes them as ``runs=`` to the functions that would otherwise find them again by reading
    every sample's vectors (:func:`scene_rows`, called several times an evaluation); :meth:`of`
    then reads any vectors' rows at the runs' starts, and :meth:`at` restricts the runs to a
    subset of the samples."""

    vectors: tuple
    index: np.ndarray
    shape: tuple
    starts: np.ndarray

    @classmethod
    def steps(cls, n_steps: int, per_step: int) -> "SceneRuns":
        """Runs of ``per_step`` consecutive samples each, ``n_steps`` of them (a cube region's
        time steps, each over its pixels), with no vectors yet (:meth:`of` reads them).

        Parameters
        ----------
        n_steps : int
            Number of runs (time steps).
        per_step : int
            Number of consecutive samples in each run.
        """
        return cls(
            (), np.repeat(np.arange(n_steps), per_step), (n_steps * per_step,), np.arange(n_steps) * per_step
        )

    @property
    def count(self) -> int:
        """Number of runs, R."""
        return int(self.starts.size)

    def of(self, *vectors_km) -> "SceneRuns":
        """These runs with ``vectors_km`` (broadcastable to the samples' shape + (3,)) read at
        each run's first sample.  The caller vouches that each vector is the same within a run
        (this is not checked: checking is the scan the runs are passed to avoid).  ValueError
        for vectors of another shape.

        Parameters
        ----------
        *vectors_km : ndarray
            The runs' shared 3-vectors, km, each broadcastable to the samples' shape + (3,).
        """
        vs = np.broadcast_arrays(*(np.asarray(v, float) for v in vectors_km))
        if int(np.prod(vs[0].shape[:-1])) != self.index.size or vs[0].shape[-1] != 3:
            raise ValueError(f"scene runs of {self.index.size} samples given vectors of shape {vs[0].shape}")
        return SceneRuns(
            tuple(np.take(v.reshape(-1, 3), self.starts, axis=0) for v in vs),
            self.index,
            vs[0].shape[:-1],
            self.starts,
        )

    def at(self, samples) -> "SceneRuns":
        """The runs of the flattened samples ``samples`` (increasing indices), as a flat
        sample set of their own, with no vectors yet (:meth:`of` reads them).

        Parameters
        ----------
        samples : ndarray of int
            Flat indices of the samples kept, increasing.
        """
        run = self.index[np.asarray(samples, dtype=np.intp)]
        new = np.empty(run.size, bool)
        new[:1] = True
        np.not_equal(run[1:], run[:-1], out=new[1:])
        return SceneRuns((), np.cumsum(new) - 1, (run.size,), np.flatnonzero(new))

    def expand(self, per_run) -> np.ndarray:
        """Values per run, (R, ...), to values per sample, shape + (...) (read-only: one run is
        broadcast, not copied).

        Parameters
        ----------
        per_run : ndarray
            Values per run, shape (R, ...).
        """
        per_run = np.asarray(per_run)
        if self.count == 1:
            return np.broadcast_to(per_run[0], self.shape + per_run.shape[1:])
        # np.take: faster than numpy's fancy indexing for rows of several values
        return np.take(per_run, self.index, axis=0).reshape(self.shape + per_run.shape[1:])


def scene_runs(*vectors_km, runs: SceneRuns | None = None) -> SceneRuns | None:
    """The samples' runs of shared 3-vectors: a survey cube's time step shares the satellite, the
    Sun and the Moon, so a batch of whole steps is one run per step, and a scene quantity
    (a body's direction, the Earth hiding a star) is computed once per run.  None where that
    would not save work: a single sample, or more runs than half the samples.  ``runs``: the
    samples' runs when the caller knows them (:class:`SceneRuns`; not found again).

    Parameters
    ----------
    *vectors_km : ndarray
        The samples' 3-vectors (e.g. satellite, Sun and Moon positions, km), broadcastable to one
        shape + (3,).
    runs : SceneRuns, optional
        The samples' runs when the caller knows them (returned, not found again).
    """
    vs = np.broadcast_arrays(*(np.asarray(v, float) for v in vectors_km))
    shape = vs[0].shape[:-1]
    flat = [v.reshape(-1, 3) for v in vs]
    n = flat[0].shape[0]
    if vs[0].ndim < 2 or n < 2:
        return None
    if runs is not None:
        return None if runs.count > n // 2 else runs.of(*vs)
    new = np.zeros(n, bool)
    new[0] = True
    for f in flat:
        # read-only, said explicitly: numpy warns when numba asks a broadcast view whether it is writeable
        f.flags.writeable = False
        _mark_changed_rows(f, new)
    starts = np.flatnonzero(new)
    if starts.size > n // 2:
        return None
    return SceneRuns(tuple(f[starts].copy() for f in flat), np.cumsum(new) - 1, shape, starts)


@njit(cache=True, nogil=True)
def _mark_changed_rows(f, new):
    """new[i] |= row i of ``f`` (N, 3) differs from row i - 1 (NaN differs from everything);
    rows already marked are not compared (one pass instead of numpy's four per vector)."""
    for i in range(1, f.shape[0]):
        if not new[i] and (f[i, 0] != f[i - 1, 0] or f[i, 1] != f[i - 1, 1] or f[i, 2] != f[i - 1, 2]):
            new[i] = True


def scene_rows(*vectors_km, runs: SceneRuns | None = None) -> SceneRuns:
    """The broadcastable 3-vectors' :func:`scene_runs`, or, where that finds none, every sample
    a run of its own: one form for the code that computes scene quantities per run and reads
    them per sample (``vectors``, ``index``, ``expand``) whatever the samples.  ``runs``: the
    samples' runs when the caller knows them (:class:`SceneRuns`; read, not found again).

    Parameters
    ----------
    *vectors_km : ndarray
        The samples' 3-vectors (e.g. satellite, Sun and Moon positions, km), broadcastable to one
        shape + (3,).
    runs : SceneRuns, optional
        The samples' runs when the caller knows them (read, not found again).
    """
    if runs is not None:
        return runs.of(*vectors_km)
    vs = np.broadcast_arrays(*(np.asarray(v, float) for v in vectors_km))
    shape = vs[0].shape[:-1]
    n = int(np.prod(shape))
    return scene_runs(*vs) or SceneRuns(
        tuple(v.reshape(-1, 3) for v in vs), np.arange(n), shape, np.arange(n)
    )


def rows_at(vectors, shape, index) -> np.ndarray:
    """The 3-vectors ``vectors`` (broadcast to ``shape`` + (3,)) at the flat sample indices
    ``index``, (len(index), 3): by np.take, faster than numpy's boolean or fancy indexing of
    (N, 3) rows.

    Parameters
    ----------
    vectors : ndarray
        3-vectors broadcastable to ``shape`` + (3,).
    shape : tuple of int
        The samples' shape.
    index : ndarray of int
        Flat sample indices.
    """
    return np.take(
        np.broadcast_to(np.asarray(vectors, float), tuple(shape) + (3,)).reshape(-1, 3), index, axis=0
    )


def tiled_period(vectors, runs: SceneRuns | None) -> int | None:
    """L when the 3-vectors ``vectors`` (..., 3; flattened, N rows) are their first L rows
    repeated once per scene run of ``runs`` (a cube batch: the same lines of sight at every
    time step), checked exactly, so that what depends on them alone is computed on L rows and
    tiled; else None.

    Parameters
    ----------
    vectors : ndarray
        3-vectors, shape (..., 3) (flattened: N rows).
    runs : SceneRuns or None
        The samples' scene runs; None gives None.
    """
    if runs is None or runs.count < 2:
        return None
    flat = np.asarray(vectors).reshape(-1, 3)
    period = flat.shape[0] // runs.count
    if period * runs.count != flat.shape[0]:
        return None
    blocks = flat.reshape(runs.count, period, 3)
    return period if np.array_equal(blocks, np.broadcast_to(blocks[:1], blocks.shape)) else None


def shared_vectors(*vectors_km):
    """The 3-vectors as single vectors when every sample shares each of them (one scene, as a
    survey cube's time step), else None (also for a single sample).

    Parameters
    ----------
    *vectors_km : ndarray
        The samples' 3-vectors, km, shape (..., 3).
    """
    runs = scene_runs(*vectors_km)
    return None if runs is None or runs.count > 1 else tuple(v[0] for v in runs.vectors)
