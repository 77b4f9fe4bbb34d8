# Shared settings of the rules: where results go, which config file the run uses, the blocks.
from straylight.config import campaign_from_dict as _campaign_from_dict
from straylight.timegrid import time_blocks as _time_blocks

CONFIG_PATH = workflow.configfiles[-1]
RESULTS = f"results/{config['campaign']['name']}"
LOGS = f"{RESULTS}/logs"
_CAMPAIGN = _campaign_from_dict(dict(config), CONFIG_PATH)
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
