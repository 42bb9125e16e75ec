"""Reading the JSON files of a seed folder (coco.json, boxes3d.json): one place that turns a
missing, unreadable or older file into a :class:`DamagedFileError` naming it and the remedy."""

from __future__ import annotations

import json
from pathlib import Path

from . import FORMAT_VERSION, VERSION_REMEDY
from .hdf5 import REMEDY, DamagedFileError


def read_json_file(path: Path, what: str):
    """The parsed document at ``path`` (``what`` names the kind of file in the error)."""
    try:
        return json.loads(path.read_bytes())
    except FileNotFoundError:
        raise DamagedFileError(f"{path}: no such file; {REMEDY}") from None
    except (OSError, ValueError) as exc:
        raise DamagedFileError(f"{path}: unreadable {what} ({exc.__class__.__name__}); {REMEDY}") from None


def check_format_version(path: Path, version) -> None:
    """Refuse a file written by another format version, saying how to regenerate it."""
    if version != FORMAT_VERSION:
        raise DamagedFileError(f"{path}: format {version!r}, this reader reads {FORMAT_VERSION} ({VERSION_REMEDY})")
