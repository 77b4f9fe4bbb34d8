"""What the sunlit and the moonlit Earth's look-up tables share as objects and as builds.

Both tables hold, per door state, the direct and door coefficients of the Earth lit by a lamp
(the Sun or the Moon) over a few angles, interpolated as
:mod:`straylight.sources.earthshine.lookup` does.  :class:`LampTable` is their common
base: their .npz file (``save``, ``load``: the axes and other arrays, one direct and one door
table per door state, the scalars as JSON metadata) and the scene runs whose lamp lights no
Earth in view (``dark_runs``).  :func:`build_lamp_table` holds the steps their builds share:
the scenes run in threads with a progress bar (:func:`_run_scenes`), the per-door-state tables
gathered, the asinh scale, and the validation's largest error and the build's time recorded.
The tables are :class:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT` (built by
:mod:`straylight.sources.earthshine.sunlit_build`) and
:class:`~straylight.sources.earthshine.moonlit_table.MoonlitLUT` (built by
:mod:`straylight.sources.earthshine.moonlit_build`).
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Callable, ClassVar, NamedTuple

import numpy as np

from straylight.errors import InputError
from straylight.sources.earthshine.lookup import _beyond_dark_zenith, _dark_lamp_zenith_deg

__all__ = ["LampTable", "TableScenes", "build_lamp_table"]


def _save_tables(path, axes: dict, direct: dict, door: dict, meta: dict) -> None:
    """Axes, per-door-state tables and metadata to one .npz, atomically (concurrent builders
    never share a temporary)."""
    p = Path(path)
    tmp = p.with_name(f"{p.stem}.{os.getpid()}.partial.npz")
    arrays = dict(axes)
    for s in direct:
        arrays[f"direct_{s:g}"] = direct[s]
        arrays[f"door_{s:g}"] = door[s]
    np.savez(tmp, meta=np.array(json.dumps({"states": [float(s) for s in direct], **meta})), **arrays)
    tmp.replace(p)


def _load_tables(path, what: str):
    """(arrays, metadata, direct, door) of a table :func:`_save_tables` wrote; InputError naming
    the file when it is not one."""
    try:
        z = np.load(path, allow_pickle=False)
        meta = json.loads(str(z["meta"]))
        states = meta["states"]
        return z, meta, {s: z[f"direct_{s:g}"] for s in states}, {s: z[f"door_{s:g}"] for s in states}
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"{path}: not a valid {what} look-up table ({exc}); delete it to rebuild") from exc


class LampTable:
    """Base of the earthshine look-up tables (dataclasses with ``direct`` and ``door``: door
    state -> array, the lamp's zenith angle along one axis): their file and their dark runs.
    A subclass names its fields in the class attributes below."""

    #: the arrays saved besides the per-door-state tables, in the file's order
    FILE_ARRAYS: ClassVar[tuple[str, ...]] = ()
    #: the scalars saved as JSON metadata, in the file's order, each with the type it is read as
    FILE_META: ClassVar[dict[str, Callable]] = {}
    #: what the table is, in the error naming a file that is not one
    WHAT: ClassVar[str] = ""
    #: the (cached) property holding the lamp zenith angle, deg, beyond which the table is 0
    DARK_ZENITH: ClassVar[str] = ""

    direct: dict
    door: dict

    def _dark_zenith_deg(self, zenith_nodes_deg: np.ndarray, axis: int) -> float:
        """The lamp zenith angle beyond which every table is 0, deg (:func:`_dark_lamp_zenith_deg`),
        for the lamp zenith nodes ``zenith_nodes_deg`` (deg) along ``axis`` of the tables."""
        return _dark_lamp_zenith_deg(zenith_nodes_deg, (*self.direct.values(), *self.door.values()), axis)

    def dark_runs(self, rows) -> np.ndarray:
        """Per run of ``rows`` (scene runs of (satellite, lamp)): no Earth lit by the lamp in
        view, the table 0 (the lamp's zenith angle beyond the property :attr:`DARK_ZENITH` names).

        Parameters
        ----------
        rows : SceneRuns
            Scene runs of (satellite, lamp) positions, km.

        Returns
        -------
        ndarray of bool, shape (runs,)
        """
        return _beyond_dark_zenith(rows, getattr(self, self.DARK_ZENITH))

    def save(self, path) -> None:
        """Write the table to ``path``.

        Parameters
        ----------
        path : str or Path
            The .npz file, written atomically (the arrays of :attr:`FILE_ARRAYS`, one direct and
            one door table per door state, and the scalars of :attr:`FILE_META` as JSON).
        """
        _save_tables(
            path,
            {k: getattr(self, k) for k in self.FILE_ARRAYS},
            self.direct,
            self.door,
            {k: getattr(self, k) for k in self.FILE_META},
        )

    @classmethod
    def load(cls, path):
        """Read a table :meth:`save` wrote.

        Parameters
        ----------
        path : str or Path
            A .npz file :meth:`save` wrote.

        Returns
        -------
        LampTable
            An instance of the class it is called on.

        Raises
        ------
        InputError
            When the file cannot be read or is not such a table.
        """
        z, meta, direct, door = _load_tables(path, cls.WHAT)
        return cls(
            direct=direct,
            door=door,
            **{k: z[k] for k in cls.FILE_ARRAYS},
            **{k: kind(meta[k]) for k, kind in cls.FILE_META.items()},
        )


# -- the builds ---------------------------------------------------------------------------------
def _asinh_scale(direct: dict, door: dict) -> float:
    """The tables' asinh scale: the 1st percentile of their positive values (linear below it,
    logarithmic above)."""
    positive = np.concatenate([v[v > 0] for v in list(direct.values()) + list(door.values())])
    return float(np.percentile(positive, 1)) if positive.size else 1e-30


def _run_scenes(fn, tasks: list, workers: int, what: str) -> list:
    """fn(*task) for every task (a scene each), in ``workers`` threads (the sums are compiled
    and release the GIL), with a progress bar on standard error once it runs for more than a
    few seconds.  Each task's result does not depend on the threads, so the table is the same
    byte for byte whatever ``workers`` is."""
    from concurrent.futures import ThreadPoolExecutor, as_completed

    from tqdm import tqdm

    results = [None] * len(tasks)
    tty = sys.stderr.isatty()
    with tqdm(
        total=len(tasks),
        desc=what,
        unit="scene",
        delay=3.0,
        mininterval=1.0 if tty else 60.0,
        leave=not tty,
        file=sys.stderr,
    ) as bar:
        if workers <= 1 or len(tasks) <= 1:
            for i, t in enumerate(tasks):
                results[i] = fn(*t)
                bar.update()
        else:
            with ThreadPoolExecutor(max_workers=workers) as ex:
                futures = {ex.submit(fn, *t): i for i, t in enumerate(tasks)}
                try:
                    for f in as_completed(futures):
                        results[futures[f]] = f.result()
                        bar.update()
                except BaseException:  # Ctrl-C or a failed scene: the queued scenes are not run
                    for f in futures:
                        f.cancel()
                    raise
    return results


class TableScenes(NamedTuple):
    """The scenes a lamp's table is summed from: ``scene(*task)`` -> (direct, door, ...), arrays
    (the task's nodes, door states ascending) per unit irradiance of the lamp, one task a scene
    in the table's node order; the table's shape per door state; its name (progress bar)."""

    scene: Callable
    tasks: list
    shape: tuple
    what: str


def build_lamp_table(off, scenes: TableScenes, make, error_at, floor: float, workers: int):
    """A table built and validated: ``scene(*task)`` for every task in ``workers`` threads (one
    scene a task, its nodes contiguous in the table's C order), the per-door-state tables
    gathered from the scenes, the table made, then validated state by state.

    Parameters
    ----------
    off : EarthGrid
        The off-field transfer and Earth grid (its door states).
    scenes : TableScenes
        The scene function, its tasks, the table's shape per door state and its name.
    make : callable
        ``make(direct, door, scale, results)`` -> the table (a :class:`LampTable`), with
        ``direct`` and ``door`` door state -> array of ``shape``, ``scale`` the asinh scale
        (:func:`_asinh_scale`) and ``results`` the scenes' results.
    error_at : callable
        ``error_at(table, state)`` -> ndarray: the table's errors at the validation points,
        fractions of the total, for door state ``state`` (deg).
    floor : float
        The darkest sky; 0: no validation (the error is then NaN).
    workers : int
        Threads.

    Returns
    -------
    LampTable
        With ``validation_max_rel_error`` (the largest of the errors, a fraction of the total)
        and ``build_seconds`` (s, wall).
    """
    t_start = time.perf_counter()
    off._kernel_tables  # the door's tables once, before the threads share them
    shape = scenes.shape
    results = _run_scenes(scenes.scene, scenes.tasks, workers, scenes.what)
    ascending = sorted(off.door_states_deg)
    direct, door = {}, {}
    for state in off.door_states_deg:
        j = ascending.index(state)
        direct[state] = np.concatenate([res[0][:, j] for res in results]).reshape(shape)
        door[state] = np.concatenate([res[1][:, j] for res in results]).reshape(shape)
    table = make(direct, door, _asinh_scale(direct, door), results)
    errs = [error_at(table, state) for state in off.door_states_deg]
    table.validation_max_rel_error = float(np.max(errs)) if floor > 0 else float("nan")
    table.build_seconds = time.perf_counter() - t_start
    return table
