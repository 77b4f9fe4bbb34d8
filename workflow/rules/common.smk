# Shared settings of the rules: where results go, which config file the run uses, the blocks.
from pathlib import Path

from snakemake.exceptions import WorkflowError

from straylight.config import campaign_from_dict as _campaign_from_dict
from straylight.config import resolve_config_files as _resolve_config_files
from straylight.cube.footprint import footprint_from_config as _footprint_from_config
from straylight.limits.cube import summary_processes as _summary_processes
from straylight.cube.timegrid import time_blocks as _time_blocks
from straylight.util.healpix import load_without_plotting as _load_healpy_without_plotting

from straylight.sky.timeutil import ignore_dubious_years as _ignore_dubious_years

_load_healpy_without_plotting()  # the parse's footprint needs healpy's pixel functions only
# ERFA's "dubious year" warnings (a campaign beyond the leap-second table): harmless inside DE405,
# which the campaign's check below enforces with a line of its own
_ignore_dubious_years()

# Snakemake lists the workflow's own configfile after the command line's --configfile ones,
# but merges the latter over it: the files in increasing precedence.
_CLI_CONFIG_FILES = [str(Path(f).resolve()) for f in workflow.overwrite_configfiles]
_CONFIG_FILES = [
    f for f in workflow.configfiles if str(Path(f).resolve()) not in _CLI_CONFIG_FILES
] + _CLI_CONFIG_FILES
# relative paths (instrument, TLE, mask, Gaia files) against the file that set them; errors name it
_RESOLVED, _CONFIG_SOURCES, CONFIG_PATH = _resolve_config_files(dict(config), _CONFIG_FILES)
CONFIG_PATH = str(CONFIG_PATH)
_CAMPAIGN = _campaign_from_dict(_RESOLVED, CONFIG_PATH, _CONFIG_SOURCES)
config.clear()
config.update(_CAMPAIGN.config_mapping())  # absolute paths and the schema's defaults, as the scripts see it
RESULTS = f"results/{config['campaign']['name']}"
#: the run's working files (the cube's block sentinels and work stores, logs, run summaries): not
#: products; everything else in RESULTS is in the README's products table
WORK = f"{RESULTS}/work"
LOGS = f"{WORK}/logs"
#: the observability store the cube's workers fill, published as observability.zarr once every
#: time block is done (rule background)
OBSERVABILITY_WORK_STORE = f"{WORK}/background_blocks/observability.zarr"
#: the limits store the cube's workers fill (every sample's limit), published as limits.zarr with
#: the per-pixel summaries added (rule limits)
LIMITS_WORK_STORE = f"{WORK}/background_blocks/limits.zarr"
TIME_BLOCKS = list(
    range(
        len(
            _time_blocks(
                len(_CAMPAIGN.times),
                float(config["campaign"]["cadence_s"]),
                float(config["campaign"].get("time_block_hours", 6)),
            )
        )
    )
)
#: the time blocks of each cube job (rule background_blocks): all in one job, or
#: compute.time_blocks_per_job per job
_PER_JOB = (config.get("compute") or {}).get("time_blocks_per_job") or max(1, len(TIME_BLOCKS))
CUBE_JOBS = [TIME_BLOCKS[i:i + _PER_JOB] for i in range(0, len(TIME_BLOCKS), _PER_JOB)]
#: processes rule background_init may use for an earthshine table or faint-star map it must
#: compute (once per model and footprint): the run's --cores; 1 where none is given (a cluster
#: run, whose profile raises the rule's threads instead)
try:
    INIT_BUILD_PROCESSES = max(1, int(workflow.cores))
except WorkflowError:
    INIT_BUILD_PROCESSES = 1
#: the cube jobs' outputs: every time block of the three stores written once all exist (the
#: limits and the figures start from them, beside rule background)
CUBE_PARTS = [f"{WORK}/background_blocks/part_{i}.json" for i in range(len(CUBE_JOBS))]
#: processes (cores) of rule limits' per-pixel summaries: 1 for a month at nside 32, 2 from a few
#: GB of limits on (limits.cube.summary_processes); a core it does not need runs another rule
_N_PIXELS = _footprint_from_config(config["footprint"], Path(CONFIG_PATH).parent).pixels.size
LIMITS_PROCESSES = _summary_processes(len(_CAMPAIGN.times) * _N_PIXELS * len(_CAMPAIGN.bands), 2)
#: the order in which the jobs after the cube start when cores are few (higher first): the limits
#: and the time series (the longest job) first, then the sky maps ahead of provenance, which needs
#: the limits only: on 2 cores the three jobs and provenance then end about together
FIGURE_PRIORITY = {"limits": 2, "time_series": 2, "sky_maps": 1}
