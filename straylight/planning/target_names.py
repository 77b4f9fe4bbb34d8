"""The target list of ``straylight visibility --targets``: read, checked and its names resolved.

The file is a CSV with the columns ``name``, ``ra`` and ``dec`` (ICRS, deg; ``ra_deg`` and
``dec_deg`` accepted; blank lines and lines starting with ``#`` skipped).  A row with both
coordinates uses them and the name only labels its outputs; a row with neither has its name
resolved, in this order:

1. a packaged field or galaxy (``straylight/data/extragalactic_fields.csv``: COSMOS, HDF-N/GOODS-N,
   CDF-S/GOODS-S, HUDF, SXDS/UDS, EGS/AEGIS, Stripe 82, M31, M33, M81, M101, LMC, SMC, NGC 253,
   the Coma cluster, and their aliases), its centre as published (each row names the paper or
   catalogue);
2. a star of the campaign's catalog, as ``straylight image --star`` finds it: a HIP number
   (``HIP 32349``, ``HIP32349`` or ``32349``) or an IAU name of
   :data:`straylight.catalog.hipparcos.BRIGHT_STAR_HIP` (``Sirius``), at the catalog's position.

Names match whatever their case, spaces, hyphens and underscores (``ngc253`` is ``NGC 253``).
Every refusal is one line naming the file, the row and the value.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from straylight.errors import InputError

__all__ = [
    "FIELDS_CSV",
    "Targets",
    "packaged_fields",
    "name_key",
    "sanitized",
    "read_targets",
]

#: the packaged fields and galaxies (name, aliases, centre as published, reference)
FIELDS_CSV = Path(__file__).resolve().parents[1] / "data" / "extragalactic_fields.csv"

_COLUMNS = {"name": ("name",), "ra": ("ra", "ra_deg"), "dec": ("dec", "dec_deg")}


@dataclass
class Targets:
    """A resolved target list.

    Attributes
    ----------
    names : list of str
        The targets' names as given.
    files : list of str
        Each name sanitized for file names (:func:`sanitized`), unique.
    ra_deg, dec_deg : ndarray of float, shape (m,)
        ICRS position, deg (RA in [0, 360)).
    source : list of str
        Where each position comes from: ``"input"``, ``"field: <reference>"`` or
        ``"catalog: HIP <n> (<catalog file>)"``.
    """

    names: list
    files: list
    ra_deg: np.ndarray
    dec_deg: np.ndarray
    source: list

    def __len__(self) -> int:
        return len(self.names)


def name_key(name: str) -> str:
    """A name as it is matched: lower case, letters and digits only (``"NGC 253"`` -> ``"ngc253"``).

    Parameters
    ----------
    name : str
        A target name.

    Returns
    -------
    str
        The key.
    """
    return re.sub(r"[^0-9a-z]", "", str(name).lower())


def sanitized(name: str) -> str:
    """A name as a file name: letters, digits, ``.``, ``-`` and ``_`` kept, any other run of
    characters one ``_`` (``"NGC 253"`` -> ``"NGC_253"``).

    Parameters
    ----------
    name : str
        A target name.

    Returns
    -------
    str
        The file-name form (never empty, never starting with a dot).
    """
    s = re.sub(r"[^0-9A-Za-z._-]+", "_", str(name).strip()).strip("_")
    s = s.lstrip(".")
    return s or "target"


def packaged_fields() -> dict:
    """The packaged fields and galaxies by :func:`name_key` of their names and aliases.

    Returns
    -------
    dict of str to tuple
        key -> (name, RA deg, Dec deg, reference): the centre as published in
        :data:`FIELDS_CSV` (sexagesimal, ICRS/J2000) in degrees.
    """
    from astropy.coordinates import Angle

    out = {}
    with open(FIELDS_CSV, newline="", encoding="utf-8") as f:
        for row in csv.DictReader(line for line in f if not line.startswith("#")):
            ra = Angle(row["ra_hms"], unit="hourangle").deg
            dec = Angle(row["dec_dms"], unit="deg").deg
            entry = (row["name"], float(ra), float(dec), row["reference"])
            for alias in [row["name"], *row["aliases"].split(";")]:
                if alias.strip():
                    out[name_key(alias)] = entry
    return out


def _read_rows(path: Path) -> list[tuple[int, int, dict]]:
    """(row number, line number, {name, ra, dec} text) of each data row of the CSV."""
    if not path.exists():
        raise InputError(f"--targets {path}: file does not exist")
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            lines = [
                (i + 1, line)
                for i, line in enumerate(f)
                if line.strip() and not line.lstrip().startswith("#")
            ]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"--targets {path}: cannot read ({type(exc).__name__}: {exc})") from None
    if not lines:
        raise InputError(f"--targets {path}: no header and no rows (expected the columns name, ra, dec)")
    reader = csv.reader(line for _, line in lines)
    header = [h.strip().lower() for h in next(reader)]
    where = {}
    for key, names in _COLUMNS.items():
        found = next((header.index(n) for n in names if n in header), None)
        if found is None:
            raise InputError(
                f"--targets {path}: missing column {key!r} (accepted: {', '.join(names)}); "
                f"found {', '.join(header) or 'none'}"
            )
        where[key] = found
    rows = []
    for k, ((line_no, _), values) in enumerate(zip(lines[1:], reader)):
        get = {key: (values[i].strip() if i < len(values) else "") for key, i in where.items()}
        rows.append((k + 1, line_no, get))
    if not rows:
        raise InputError(f"--targets {path}: no rows after the header")
    return rows


def read_targets(path, catalog=None) -> Targets:
    """Read a target list and resolve its names (see the module docstring).

    Parameters
    ----------
    path : str or path-like
        The CSV (columns ``name``, ``ra``, ``dec``; coordinates in deg, ICRS, or both empty).
    catalog : callable or str or path-like, optional
        The star catalog (``source_id``, ``ra``, ``dec``) for HIP numbers and star names, or a
        function giving its path, called only when a row needs it (e.g. the campaign's
        default catalog, built on first use).  None: star names are refused.

    Returns
    -------
    Targets
        The targets in file order.

    Raises
    ------
    InputError
        A missing file or column, no rows, an empty name, only one of ra and dec, a coordinate
        that is not a number or out of range, an unknown name, a HIP number not in the catalog,
        two rows with the same name (as file names): one line naming the file, row and value.
    """
    from straylight.planning.pointings import check_radec

    path = Path(path)
    rows = _read_rows(path)
    fields = None
    stars = None
    names, files, ra, dec, source = [], [], [], [], []
    seen: dict = {}
    for row, line, v in rows:
        at = f"--targets {path}: row {row} (line {line})"
        name = v["name"]
        if not name:
            raise InputError(f"{at}: name is empty; every target needs a name (it names its output files)")
        if bool(v["ra"]) != bool(v["dec"]):
            raise InputError(f"{at}: name {name!r}: give both ra and dec, or neither to look the name up")
        if v["ra"]:
            r, d = check_radec([v["ra"]], [v["dec"]], lambda i: f"{at}: name {name!r}: ")
            where = "input"
        else:
            fields = packaged_fields() if fields is None else fields
            hit = fields.get(name_key(name))
            if hit is not None:
                r, d, where = [hit[1]], [hit[2]], f"field {hit[0]}: {hit[3]}"
            else:
                number = _star_number(name)
                if number is None:
                    raise InputError(
                        f"{at}: name {name!r} is neither a packaged field ({FIELDS_CSV.name}: "
                        f"{', '.join(sorted({e[0] for e in fields.values()}))}) nor a catalog star (a HIP "
                        "number or a bright star's IAU name); give its ra and dec"
                    )
                if stars is None:
                    stars = _catalog_positions(catalog, at, name)
                rows_hit = np.flatnonzero(stars["source_id"] == number)
                if rows_hit.size == 0:
                    raise InputError(
                        f"{at}: name {name!r}: HIP {number} is not in the catalog {stars['path']}"
                    )
                j = int(rows_hit[0])
                r, d = [float(stars["ra"][j]) % 360.0], [float(stars["dec"][j])]
                where = f"catalog: HIP {number} ({Path(stars['path']).name})"
        f = sanitized(name)
        if f.lower() in seen:
            raise InputError(
                f"{at}: name {name!r} gives the file name {f!r}, as row {seen[f.lower()]} does; "
                "target names must differ"
            )
        seen[f.lower()] = row
        names.append(name)
        files.append(f)
        ra.append(float(r[0]))
        dec.append(float(d[0]))
        source.append(where)
    return Targets(names, files, np.array(ra), np.array(dec), source)


def _star_number(name: str) -> int | None:
    """The HIP number a name stands for (``HIP 32349``, ``32349``, an IAU bright-star name), else None."""
    from straylight.catalog.hipparcos import BRIGHT_STAR_HIP

    key = name_key(name)
    m = re.fullmatch(r"(?:hip)?(\d+)", key)
    if m:
        return int(m.group(1))
    return BRIGHT_STAR_HIP.get(key)


def _catalog_positions(catalog, at: str, name: str) -> dict:
    """The catalog's ``source_id``, ``ra`` and ``dec`` (deg) and its path."""
    if catalog is None:
        raise InputError(f"{at}: name {name!r}: a star name needs a star catalog")
    path = Path(catalog() if callable(catalog) else catalog)
    try:
        if path.suffix.lower() == ".parquet":
            import pyarrow.parquet as pq

            t = pq.read_table(path, columns=["source_id", "ra", "dec"])
            cols = {k: np.asarray(t.column(k).to_numpy()) for k in ("source_id", "ra", "dec")}
        else:
            from astropy.table import Table

            t = Table.read(path)
            cols = {k: np.asarray(t[k]) for k in ("source_id", "ra", "dec")}
    except Exception as exc:
        raise InputError(
            f"{at}: name {name!r}: the catalog {path} has no source_id, ra and dec to look stars up in "
            f"({type(exc).__name__}: {exc})"
        ) from None
    cols["path"] = str(path)
    return cols
