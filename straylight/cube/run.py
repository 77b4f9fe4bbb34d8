"""The cube's run: the time blocks of one Snakemake job, each marked done by its sentinel.

One job computes many time blocks (:func:`run_time_blocks`: all of them, or
``compute.time_blocks_per_job``) on workers started once per job
(:func:`~straylight.cube.executors.region_pool`); each (time block, pixel block) region is
written to its own part of the stores exactly once.  A time block is marked done by its own
sentinel file (:func:`block_sentinel`, holding its :class:`BlockReport`) only after all its
regions are written, so a killed job redoes only the unfinished time blocks and, the
computation being deterministic, gives identical bytes.
"""

from __future__ import annotations

import json
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

from straylight.cube.executors import Execution, region_pool
from straylight.cube.layout import CubeStores, cube_pixel_blocks, cube_time_blocks

if TYPE_CHECKING:
    from straylight.config import Campaign
    from straylight.cube.footprint import Footprint

__all__ = ["BlockReport", "block_sentinel", "clear_block_sentinels", "run_time_blocks"]


@dataclass
class BlockReport:
    """A finished time block: its index, its pixel blocks, its samples and the seconds from its
    first region's submission to its last region's end.

    Attributes
    ----------
    time_block : int
        Index of the time block.
    pixel_blocks : int
        Number of pixel blocks (regions) written.
    samples : int
        Time samples x footprint pixels of the block.
    seconds : float
        Wall-clock time from the first region's submission to the last region's end, s.
    """

    time_block: int
    pixel_blocks: int
    samples: int
    seconds: float


def block_sentinel(done_dir, block_index: int) -> Path:
    """The file marking time block ``block_index`` done (its BlockReport as JSON).

    Parameters
    ----------
    done_dir : str or path-like
        Folder of the sentinels.
    block_index : int
        Index of the time block.

    Returns
    -------
    pathlib.Path
        ``done_dir/block_<block_index>.json`` (not checked for existence).
    """
    return Path(done_dir) / f"block_{block_index}.json"


def clear_block_sentinels(done_dir) -> int:
    """Remove every time block's sentinel from ``done_dir`` (a fresh store has no block done);
    returns how many were removed.

    Parameters
    ----------
    done_dir : str or path-like
        Folder of the sentinels.

    Returns
    -------
    int
        Number of sentinel files removed.
    """
    removed = 0
    for p in Path(done_dir).glob("block_*.json"):
        p.unlink()
        removed += 1
    return removed


class _BlockWork(NamedTuple):
    """The time blocks :func:`run_time_blocks` has left to do: their indices, every time block's
    (start, stop) time indices, the pixel blocks (slices), the stored faint-star map (None: no
    stars) and the sentinels' folder."""

    todo: list
    time_blocks: list
    pixel_blocks: list
    faint: object
    done_dir: object


def _run_regions(campaign, fp, stores, stars_path, execution, work: _BlockWork, log) -> None:
    """Run the regions of ``work``'s time blocks, each time block's sentinel written once all its
    pixel blocks are (:func:`run_time_blocks`)."""
    from concurrent.futures import FIRST_COMPLETED

    from straylight.sky.observing import scene
    from straylight.util.io import write_json_atomic

    todo, tb, p_blocks, faint, done_dir = work
    with region_pool(campaign, fp, stores, stars_path, execution) as (submit, wait):
        # a bounded window of regions in flight: the next time block's scene is computed
        # while the workers are busy, and memory does not grow with the campaign
        window = 2 * max(1, int(execution.workers)) + 1
        pending: dict = {}
        left = {b: len(p_blocks) for b in todo}
        started: dict = {}

        def finish(done):
            for fut in done:
                b, ps, t_slice = pending.pop(fut)
                seconds = fut.result()
                if log is not None:
                    log.info(
                        "chunk time %d:%d pixels %d:%d done in %.2f s",
                        t_slice.start,
                        t_slice.stop,
                        ps.start,
                        ps.stop,
                        seconds,
                    )
                left[b] -= 1
                if left[b] == 0:
                    n = (t_slice.stop - t_slice.start) * fp.pixels.size
                    rep = BlockReport(b, len(p_blocks), n, _time.perf_counter() - started[b])
                    write_json_atomic(rep.__dict__, block_sentinel(done_dir, b))

        for b in todo:
            t_slice = slice(*tb[b])
            # the satellite's and the bodies' positions once per time block, shared by its
            # pixel blocks (small: sent with each region)
            sc = scene(campaign.orbit, campaign.times[t_slice])
            started[b] = _time.perf_counter()
            for ps in p_blocks:
                while len(pending) >= window:
                    finish(wait(list(pending), return_when=FIRST_COMPLETED)[0])
                fut = submit(t_slice, ps, sc, None if faint is None else faint[ps])
                pending[fut] = (b, ps, t_slice)
        while pending:
            finish(wait(list(pending), return_when=FIRST_COMPLETED)[0])


def run_time_blocks(
    campaign: Campaign,
    fp: Footprint,
    stores,
    blocks,
    done_dir,
    stars_path=None,
    execution: Execution | None = None,
    log=None,
) -> list[BlockReport]:
    """Compute the time blocks ``blocks`` (indices) of the cube into ``stores`` (a
    :class:`~straylight.cube.layout.CubeStores`: each region's observability and limits
    are written to its observability and limits stores too, before its time block's sentinel;
    or the cube's store's path alone), each marked done by its sentinel in ``done_dir``
    (:func:`block_sentinel`) once all its pixel blocks are written; blocks already marked done
    are skipped (resume).  ``stars_path``: the star catalog (None: stars = 0).  ``execution``:
    where the regions run (:class:`~straylight.cube.executors.Execution`; None: in this
    process).  ``log`` (a logging.Logger) gets one line per finished region.
    Returns every requested block's report (a skipped one's from its sentinel).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (times, bands, chunking).
    fp : Footprint
        The survey footprint.
    stores : CubeStores or str or path-like
        The stores to write (their skeletons laid down), or background.zarr's path alone.
    blocks : iterable of int
        Time block indices, each in ``[0, number of time blocks)``.
    done_dir : str or path-like
        Folder of the sentinels.
    stars_path : str or path-like, optional
        The star catalog; None: stars = 0.
    execution : Execution, optional
        Where the regions run; None: in this process.
    log : logging.Logger, optional
        Gets a line per finished region; None: silent.

    Returns
    -------
    list of BlockReport
        One per requested block, in the order of ``blocks``.

    Raises
    ------
    IndexError
        When a block index is outside the campaign's time blocks.
    OutputError
        When a region cannot be written (from the workers).
    """
    from straylight.cube.store import stored_faint_map
    from straylight.storage.zarr_io import remove_partial_chunks

    execution = execution or Execution()
    tb = cube_time_blocks(campaign, len(campaign.times))
    blocks = [int(b) for b in blocks]
    bad = [b for b in blocks if not 0 <= b < len(tb)]
    if bad:
        raise IndexError(f"time block {bad[0]} outside 0..{len(tb) - 1}")
    stores = CubeStores.of(stores).resolved()  # workers (other hosts, other cwd) need absolute paths
    stars_path = str(Path(stars_path).resolve()) if stars_path else None
    todo = [b for b in blocks if not block_sentinel(done_dir, b).exists()]
    if log is not None and len(todo) < len(blocks):
        log.info(
            "%d of %d time blocks already done (sentinels in %s): skipped",
            len(blocks) - len(todo),
            len(blocks),
            done_dir,
        )
    p_blocks = cube_pixel_blocks(campaign, fp)
    faint = stored_faint_map(stores.cube) if (stars_path is not None and todo) else None
    # a time block is a time chunk: its half-written chunk files of a killed run go before it is redone
    removed = sum(remove_partial_chunks(s, todo) for s in stores.paths() if s is not None)
    if log is not None and removed:
        log.info("removed %d half-written chunk files of an earlier run", removed)
    if todo:
        work = _BlockWork(todo, tb, p_blocks, faint, done_dir)
        _run_regions(campaign, fp, stores, stars_path, execution, work, log)
    return [BlockReport(**json.loads(block_sentinel(done_dir, b).read_text())) for b in blocks]
