"""Helpers shared by the commands: argument types, output checks, JSON printing, the pointing."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

__all__ = ["CONFIG_HELP", "add_output_flags", "check_out", "checked_pointing", "finite_float", "print_json"]

#: The help of every command's ``--config``.
CONFIG_HELP = "campaign config (default: config/config.yaml)"


def finite_float(name: str):
    """An argparse ``type``: a finite float, else one line naming the option ``name``."""

    def conv(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return v

    return conv


def _json_default(o):
    """NumPy scalars and arrays as plain JSON values."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def print_json(obj) -> None:
    """Print ``obj`` as indented JSON on stdout (NumPy values converted)."""
    json.dump(obj, sys.stdout, indent=2, default=_json_default)
    sys.stdout.write("\n")


def check_out(args, path, flag: str = "--out", folder: bool = False) -> Path:
    """Check an output path before any work (parent exists or --parents, writable, no silent
    overwrite); see :func:`straylight.util.io.check_output_path`."""
    from straylight.util.io import check_output_path

    return check_output_path(
        path,
        flag,
        overwrite=getattr(args, "overwrite", False),
        parents=getattr(args, "parents", False),
        folder=folder,
    )


def add_output_flags(parser) -> None:
    """``--overwrite`` and ``--parents``, read by :func:`check_out`."""
    parser.add_argument("--overwrite", action="store_true", help="replace existing output files")
    parser.add_argument("--parents", action="store_true", help="create the output's missing folders")


def checked_pointing(args) -> tuple[float, float]:
    """--ra/--dec checked by the rule the pointing table's rows obey (RA wrapped to [0, 360))."""
    from straylight.planning.pointings import check_radec

    ra, dec = check_radec([args.ra], [args.dec], names=("--ra", "--dec"))
    return float(ra[0]), float(dec[0])
