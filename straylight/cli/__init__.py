"""Command-line interface: ``straylight <command> --help``.

The package parses the arguments and prints; the work is the library's.  :mod:`.parser` builds
the parser, one module per group of commands runs them: :mod:`.sky` (``ephem``, ``sky``,
``visibility``), :mod:`.image` (``image``), :mod:`.campaign` (``plan``, ``footprint``,
``catalog``, ``pst``, ``schedule``, ``config-doc``, ``run``) and :mod:`.paper` (``scenario``,
``figure``).

User mistakes (bad config, time out of range, NaN coordinates) print one clear line on stderr
and exit with status 2; no traceback.

Internal: the command line's implementation; its functions are not a Python API (users call
``straylight.cli.main`` only through the ``straylight`` command).
"""

from __future__ import annotations

import sys

from straylight.cli.campaign import cmd_run
from straylight.cli.parser import build_parser
from straylight.errors import StraylightError

__all__ = ["build_parser", "main"]


def main(argv=None) -> int:
    """Run the ``straylight`` command with ``argv`` (default: the process's arguments).

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program's name.

    Returns
    -------
    int
        The exit status: 0 done, 1 a warning that left nothing written, 2 a user mistake or an
        OS error (one line on stderr); ``straylight run`` returns Snakemake's.
    """
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and args.func is not cmd_run:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.snakemake_args = extra
    try:
        return args.func(args)
    except StraylightError as exc:
        print(f"straylight: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: one line, the shell's status for SIGINT, no traceback
        print(f"straylight {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader (e.g. `| head`) stopped: not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # disk full, permission lost while writing: one line naming the path
        where = exc.filename if exc.filename is not None else ""
        print(f"straylight: error: {where}{': ' if where else ''}{exc.strerror or exc}", file=sys.stderr)
        return 2
