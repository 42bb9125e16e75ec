"""``manifest.json``: what a finished seed folder holds (written last, so its presence means
the folder is complete). Lists every file with its size in bytes and sha256."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

MANIFEST = "manifest.json"


def sha256(path: Path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def write_manifest(folder: str | Path, info: dict) -> Path:
    """Write ``manifest.json`` = ``info`` + ``files``: {relative path: {bytes, sha256}}."""
    folder = Path(folder)
    files = {}
    for p in sorted(folder.rglob("*")):
        if p.is_file() and p.name != MANIFEST:
            files[p.relative_to(folder).as_posix()] = {"bytes": p.stat().st_size, "sha256": sha256(p)}
    path = folder / MANIFEST
    path.write_text(json.dumps(info | {"files": files}, indent=1, sort_keys=True))
    return path


def read_manifest(folder: str | Path) -> dict | None:
    """The folder's manifest, or None if it has none (an unfinished folder)."""
    path = Path(folder) / MANIFEST
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError:
        return None


def verify_manifest(folder: str | Path) -> list[str]:
    """Problems found (missing files, wrong sizes or hashes); empty if the folder is intact."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    if manifest is None:
        return [f"{folder}: no readable {MANIFEST}"]
    problems = []
    for rel, meta in manifest.get("files", {}).items():
        p = folder / rel
        if not p.is_file():
            problems.append(f"missing: {rel}")
        elif p.stat().st_size != meta["bytes"] or sha256(p) != meta["sha256"]:
            problems.append(f"changed: {rel}")
    return problems
