"""The cube's worker processes, started before the job that runs them has loaded its campaign.

A cube job (rule background_blocks) spends about two seconds importing the model's libraries
and loading its campaign before it has a region to hand out, and each worker as long again
building the model.  Started first, from this module (which imports nothing heavy), the workers
do that side by side with the job: each loads the campaign from the job's config and builds the
model (:func:`straylight.survey.cube._pool_init_from_config`), named here by a string so that
the job does not import the cube's module before they are on their way.
"""
from __future__ import annotations

from pathlib import Path


def start_region_workers(workers: int, config: dict, config_path, store, stars_path, obs_store=None,
                         lim_store=None):
    """A pool of ``workers`` spawned processes for
    :func:`~straylight.survey.cube.run_time_blocks` (``pool=``), each loading the campaign of
    ``config`` (read from ``config_path``) and building the model as it starts, for the stores
    at these paths (resolved as run_time_blocks resolves them).  Returns the pool's context
    manager; its processes start at the first tasks submitted to it."""
    from straylight.util.daskutil import call_by_name, spawned_pool

    def resolved(path):
        return str(Path(path).resolve()) if path else None

    init = ("straylight.survey.cube:_pool_init_from_config", dict(config), str(config_path),
            resolved(store), resolved(stars_path), resolved(obs_store), resolved(lim_store))
    return spawned_pool(workers, call_by_name, init)
