"""Helpers shared by the Snakemake script adapters (logging to the rule's log file)."""
import logging
import sys


def setup_logging(snakemake) -> logging.Logger:
    log_path = snakemake.log[0] if snakemake.log else None
    handlers = [logging.StreamHandler(sys.stderr)]
    if log_path:
        handlers.append(logging.FileHandler(log_path, mode="w"))
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s", handlers=handlers, force=True)
    return logging.getLogger(f"straylight.{snakemake.rule}")


def campaign(snakemake):
    from straylight.config import campaign_from_dict

    return campaign_from_dict(dict(snakemake.config), snakemake.input.config)
