"""Helpers shared by the Snakemake script adapters (logging to the rule's log file)."""
import logging
import sys


def setup_logging(snakemake) -> logging.Logger:
    log_path = snakemake.log[0] if snakemake.log else None
    handlers = [logging.StreamHandler(sys.stderr)]
    if log_path:
        handlers.append(logging.FileHandler(log_path, mode="w"))
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s", handlers=handlers, force=True)
    logging.getLogger("healpy").setLevel(logging.WARNING)  # read_map reports a mask's header at INFO
    return logging.getLogger(f"straylight.{snakemake.rule}")


def campaign(snakemake):
    from straylight.config import campaign_from_dict

    return campaign_from_dict(dict(snakemake.config), snakemake.input.config)


def end_job() -> None:
    """The job's last step: its process ends at once, without the interpreter's teardown of the
    modules it loaded (0.2-0.8 s, which Snakemake waits for before starting the next job);
    the logs are flushed first (straylight.util.daskutil.exit_without_teardown)."""
    from straylight.util.daskutil import exit_without_teardown

    exit_without_teardown(0)
