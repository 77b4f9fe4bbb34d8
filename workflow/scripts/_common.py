"""Helpers shared by the Snakemake script adapters (logging to the rule's log file)."""

import logging
import sys


def _interrupted_hook(exc_type, exc, tb):
    """Until setup_logging's hook: a Ctrl-C (it reaches every job: `straylight run` says it once)
    ends the job with status 130 and no traceback, even while it imports; anything else as
    Python reports it."""
    if issubclass(exc_type, KeyboardInterrupt):
        sys.stderr.flush()
        import os

        os._exit(130)
    sys.__excepthook__(exc_type, exc, tb)


sys.excepthook = _interrupted_hook  # set as the job imports this module, before the library


def setup_logging(snakemake) -> logging.Logger:
    """The rule's logger (its log file and stderr), with the job's error hook; also the job's
    healpy, without plotting functions (straylight.util.healpix), the job's death with
    Snakemake (die_with_snakemake), and ERFA's harmless "dubious year" warnings silenced."""
    from straylight.sky.timeutil import ignore_dubious_years
    from straylight.util.healpix import load_without_plotting

    die_with_snakemake()
    load_without_plotting()
    ignore_dubious_years()  # the campaign's times are inside DE405 (checked when the workflow was parsed)
    log_path = snakemake.log[0] if snakemake.log else None
    handlers = [logging.StreamHandler(sys.stderr)]
    if log_path:
        handlers.append(logging.FileHandler(log_path, mode="w"))
    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s %(name)s %(message)s", handlers=handlers, force=True
    )
    logging.getLogger("healpy").setLevel(logging.WARNING)  # read_map reports a mask's header at INFO
    log = logging.getLogger(f"straylight.{snakemake.rule}")
    sys.excepthook = _job_error_hook(log)
    return log


def die_with_snakemake() -> None:
    """SIGTERM to this job when Snakemake, its parent, dies (killed with SIGKILL, it cannot stop
    its jobs): the job stops instead of running on as an orphan, writing to the stores a resumed
    run writes too (straylight.execution.die_with_parent; Snakemake runs a script job as its
    own child, the shell exec'ing python).  The job's pool workers die with the job in turn."""
    import signal

    from straylight.execution import die_with_parent

    die_with_parent(signal.SIGTERM)


def _job_error_hook(log):
    """The job's handler of an uncaught exception: a user's mistake (StraylightError) or the file
    system's refusal of a named file (OSError: no space, over quota, no permission, read-only)
    logged as one line ("error: ..."), exit status 2, as the CLI does; the files being written
    are temporary ones (util.io.atomic_path), so every finished product is kept.  Anything else
    (a missing file is a wrong path: a bug) keeps its traceback."""
    import errno

    refusals = {errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM, errno.EROFS}

    def hook(exc_type, exc, tb):
        from straylight.errors import StraylightError
        from straylight.execution import exit_without_teardown

        if isinstance(exc, KeyboardInterrupt):  # a Ctrl-C reaches every job: `straylight run` says it once
            log.info("interrupted (SIGINT): stopped; the same command resumes the run")
            exit_without_teardown(130)
        if isinstance(exc, StraylightError):
            line = str(exc)
        elif isinstance(exc, OSError) and exc.filename is not None and exc.errno in refusals:
            line = (
                f"{exc.filename}: {exc.strerror or exc}; the products finished so far are kept: free space "
                "(or fix the access) and re-run"
            )
        else:
            sys.__excepthook__(exc_type, exc, tb)
            return
        log.error("error: %s", line)
        exit_without_teardown(2)

    return hook


def campaign(snakemake):
    from straylight.config import campaign_from_dict

    return campaign_from_dict(dict(snakemake.config), snakemake.input.config)


def end_job() -> None:
    """The job's last step: its process ends at once, without the interpreter's teardown of the
    modules it loaded (slow, and Snakemake waits for it before starting the next job);
    the logs are flushed first (straylight.execution.exit_without_teardown)."""
    from straylight.execution import exit_without_teardown

    exit_without_teardown(0)
