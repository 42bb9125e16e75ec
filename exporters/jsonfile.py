"""Reading the JSON files of a seed folder (coco.json, boxes3d.json, frames.json,
labels.json): one place that checks their bytes against the seed's manifest (JSON carries no
checksum of its own) and turns a missing, unreadable, damaged or older file into a
:class:`DamagedFileError` naming it and the remedy."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from . import FORMAT_VERSION, VERSION_REMEDY
from .hdf5 import REMEDY, DamagedFileError, access_error
from .manifest import ManifestError, listed_sha256


def read_checked_bytes(path: Path) -> bytes:
    """The bytes of ``path``, checked against the sha256 the manifest of the seed holding it
    lists (exporters.manifest.listed_sha256; a file outside a complete seed is not checked)."""
    data = path.read_bytes()
    try:
        digest = listed_sha256(path)
    except ManifestError as exc:
        raise DamagedFileError(f"{exc}") from None
    if digest is not None and hashlib.sha256(data).hexdigest() != digest:
        raise DamagedFileError(f"{path}: damaged file (its sha256 differs from the seed's manifest); {REMEDY}")
    return data


def read_json_file(path: Path, what: str):
    """The parsed document at ``path`` (``what`` names the kind of file in the error), its
    bytes checked by :func:`read_checked_bytes`."""
    try:
        return json.loads(read_checked_bytes(path))
    except FileNotFoundError:
        raise DamagedFileError(f"{path}: no such file; {REMEDY}") from None
    except DamagedFileError:
        raise
    except (OSError, ValueError, RecursionError) as exc:
        damage = DamagedFileError(f"{path}: unreadable {what} ({exc.__class__.__name__}); {REMEDY}")
        raise access_error(exc, path) or damage from None


def check_format_version(path: Path, version) -> None:
    """Refuse a file written by another format version, saying how to regenerate it."""
    if version != FORMAT_VERSION:
        raise DamagedFileError(f"{path}: format {version!r}, this reader reads {FORMAT_VERSION} ({VERSION_REMEDY})")
