"""Files: writing products safely, their digests, and the table cache's folder.

Every writer goes to a temporary sibling path and is renamed into place, so a crash (or a full
disk) never leaves a half-written product under the final name, and a re-run simply redoes it.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

__all__ = ["check_output_path", "atomic_path", "write_json_atomic", "sha256_path", "cache_dir"]


def check_output_path(
    path, flag: str = "--out", overwrite: bool = False, parents: bool = False, folder: bool = False
) -> Path:
    """Check, before any work, that ``path`` can be written; return it as a Path.

    The parent folder must exist (created when ``parents``), be a folder and accept a new file
    (probed by creating and removing a temporary file, so read-only file systems and missing
    permissions are caught whoever runs); an existing file is refused unless ``overwrite``.
    ``folder``: ``path`` is an output folder, created here when its parent exists (or with
    ``parents``); an existing one's files are replaced only with ``overwrite``.  Raises
    :class:`~straylight.errors.InputError` naming ``flag`` and the path.

    Parameters
    ----------
    path : str or os.PathLike
        The output file or folder.
    flag : str, optional
        The option that gave it, named by the error (default ``"--out"``).
    overwrite : bool, optional
        Accept an existing file, or replace an existing folder's files (default False).
    parents : bool, optional
        Create missing parent folders (default False).
    folder : bool, optional
        ``path`` is an output folder (default False: a file).
    """
    from straylight.errors import InputError

    p = Path(path)
    if folder:
        if p.exists() and not p.is_dir():
            raise InputError(f"{flag} {p}: exists and is not a folder")
        if p.is_dir() and any(p.iterdir()) and not overwrite:
            raise InputError(
                f"{flag} {p}: folder exists and is not empty; pass --overwrite to replace its files"
            )
        target = p
    else:
        if p.is_dir():
            raise InputError(f"{flag} {p}: is a folder, expected a file name")
        if (p.exists() or p.is_symlink()) and not overwrite:
            raise InputError(f"{flag} {p}: file exists; pass --overwrite to replace it")
        target = p.parent
    if not target.exists():
        if folder and target.parent.is_dir():
            parents = True  # the output folder itself: made like a file would be
        if not parents:
            raise InputError(f"{flag} {p}: folder {target} does not exist; create it or pass --parents")
        try:
            target.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"{flag} {p}: cannot create folder {target}: {exc.strerror or exc}") from None
    if not target.is_dir():
        raise InputError(f"{flag} {p}: {target} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".straylight-write-check.", dir=target)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(f"{flag} {p}: cannot write in {target}: {exc.strerror or exc}") from None
    return p


@contextmanager
def atomic_path(final: str | os.PathLike):
    """Yield a temporary path next to ``final``; on success move it into place.

    Parameters
    ----------
    final : str or os.PathLike
        The path the result ends at.
    """
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    # temporaries of an earlier writer killed with SIGKILL (its `finally` never ran)
    for stale in final.parent.glob(f".{final.name}.*"):
        shutil.rmtree(stale, ignore_errors=True)
    tmpdir = Path(tempfile.mkdtemp(prefix=f".{final.name}.", dir=final.parent))
    tmp = tmpdir / final.name
    try:
        yield tmp
        if final.is_dir() and not final.is_symlink():
            shutil.rmtree(final)
        elif final.exists():
            final.unlink()
        os.replace(tmp, final)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)


def write_json_atomic(obj, path: str | os.PathLike) -> None:
    """Write ``obj`` as indented JSON to ``path`` through a temporary sibling renamed into place.

    Parameters
    ----------
    obj : object
        A JSON-serialisable object.
    path : str or os.PathLike
        The file written.
    """
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2, sort_keys=False) + "\n", encoding="utf-8")


def sha256_path(path: str | Path) -> str:
    """SHA-256 of a file, or of a directory tree (relative paths and file contents, sorted).

    Parameters
    ----------
    path : str or pathlib.Path
        A file or a folder.
    """
    p = Path(path)
    h = hashlib.sha256()
    if p.is_dir():
        for f in sorted(x for x in p.rglob("*") if x.is_file()):
            h.update(str(f.relative_to(p)).encode())
            h.update(f.read_bytes())
    else:
        h.update(p.read_bytes())
    return h.hexdigest()


#: The UTF-8 byte-order mark some programs (spreadsheets) start a CSV file with
UTF8_BOM = b"\xef\xbb\xbf"


def without_bom(path):
    """``path`` as it is, or, for a file that starts with a UTF-8 byte-order mark (a CSV saved by
    a spreadsheet), its text without the mark: what astropy's ASCII readers take in place of a
    path (given the path, they read the mark into the first column's name).

    Parameters
    ----------
    path : str or Path
        A text table's file.

    Returns
    -------
    str or Path
        ``path``, or the file's text (with at least one newline, so astropy takes it as data).
    """
    try:
        with open(path, "rb") as f:
            head = f.read(len(UTF8_BOM))
    except OSError:
        return path  # the reader names the file it cannot read
    if head != UTF8_BOM:
        return path
    text = Path(path).read_text(encoding="utf-8-sig")
    return text if "\n" in text else text + "\n"


def cache_dir() -> Path:
    """Where tables are kept: $STRAYLIGHT_CACHE, else $XDG_CACHE_HOME/straylight, else
    ~/.cache/straylight.  Tables are named by the digest of everything they depend on.

    Raises InputError when the folder, or the nearest of its parents that exists, is not a
    folder (``STRAYLIGHT_CACHE`` naming a file): before a table is built, not after."""
    if os.environ.get("STRAYLIGHT_CACHE"):
        path, where = Path(os.environ["STRAYLIGHT_CACHE"]), "STRAYLIGHT_CACHE"
    else:
        path = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "straylight"
        where = "the table cache"
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                from straylight.errors import InputError

                what = "is a file" if p == path else f"is under {p}, a file"
                raise InputError(f"{where} = {path}: {what}, not a folder; point it to a folder")
            break
    return path
