"""``manifest.json``: what a finished seed folder holds (written last, so its presence means
the folder is complete). Lists every file with its size in bytes, its sha256 and its
modification time (``mtime_ns``, used to decide which files a quick check re-hashes).

One schema, one writer (:func:`write_manifest`), one reader (:func:`load_manifest`, which
raises :class:`ManifestError`; :func:`read_manifest` returns None instead) and one checker
(:func:`check_files`)."""

from __future__ import annotations

import functools
import hashlib
import json
import os
import re
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path, PurePosixPath

MANIFEST = "manifest.json"
PARTIAL_MARKER = ".buildee-partial"  # written first into a folder being generated; never listed
REQUIRED = ("format_version", "seed", "config", "files")
MAX_MANIFEST_BYTES = 256 << 20  # a manifest of 10,000 frames x 3 kinds is about 20 MB
CHECKSUM = "checksum"  # sha256 of the rest of the manifest (json_checksum); manifests before it have none


class ManifestError(ValueError):
    """A manifest that is missing, unreadable or not of our schema (the message names the file)."""


def sha256(path: Path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def sha256_many(paths: list[Path]) -> list[str]:
    """:func:`sha256` of each path, in order, hashed on every core (hashlib and file reads
    release the GIL: on 2 cores a default seed hashes in about half the time of one thread)."""
    if len(paths) < 2:
        return [sha256(p) for p in paths]
    with ThreadPoolExecutor(max_workers=min(len(paths), os.cpu_count() or 1)) as pool:
        return list(pool.map(sha256, paths))


def _entries(folder: Path) -> tuple[list[str], dict[str, str]]:
    """What ``folder`` holds apart from its own manifest.json and partial marker, as relative
    paths: (its regular files, which a manifest lists; {every other entry: what it is}, which
    no manifest lists: a symlink, a special file such as a FIFO, an empty folder). Symlinks
    are never followed."""
    files, others = [], {}
    for root, dirs, names in os.walk(folder):
        base = Path(root)
        if base != folder and not dirs and not names:
            others[base.relative_to(folder).as_posix()] = "an empty folder"
        for p in [base / n for n in dirs if (base / n).is_symlink()] + [base / n for n in names]:
            rel = p.relative_to(folder).as_posix()
            if p.is_symlink() or not p.is_file():
                others[rel] = "a symlink" if p.is_symlink() else "not a regular file"
            elif rel not in (MANIFEST, PARTIAL_MARKER):
                files.append(rel)
    return sorted(files), dict(sorted(others.items()))


def write_manifest(folder: str | Path, info: dict) -> Path:
    """Write ``manifest.json`` = ``info`` + ``files``: {relative path: {bytes, sha256, mtime_ns}},
    atomically (a temporary file renamed into place), so a manifest is whole or absent."""
    folder = Path(folder)
    rels = _entries(folder)[0]
    paths = [folder / rel for rel in rels]
    stats = [p.stat() for p in paths]
    files = {rel: {"bytes": st.st_size, "sha256": digest, "mtime_ns": st.st_mtime_ns}
             for rel, st, digest in zip(rels, stats, sha256_many(paths))}
    path = folder / MANIFEST
    tmp = folder / f".{MANIFEST}.tmp"
    doc = info | {"files": files}
    with open(tmp, "w") as f:
        f.write(json.dumps(doc | {CHECKSUM: json_checksum(doc)}, indent=1, sort_keys=True))
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def json_checksum(doc: dict) -> str:
    """sha256 of ``doc`` (e.g. a manifest without its checksum) as compact JSON with sorted keys."""
    return hashlib.sha256(json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _schema_problem(manifest) -> str | None:
    if not isinstance(manifest, dict):
        return f"holds a JSON {type(manifest).__name__}, not an object"
    missing = [k for k in REQUIRED if k not in manifest]
    if missing:
        return f"lacks {', '.join(missing)}"
    seed = manifest["seed"]
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        return f"has seed {seed!r}, not a non-negative integer"
    if not isinstance(manifest["config"], dict):
        return "has a config that is not an object"
    files = manifest["files"]
    if not isinstance(files, dict):
        return "has a file list that is not an object"
    for rel, meta in files.items():
        p = PurePosixPath(rel)
        if p.is_absolute() or ".." in p.parts or not rel:
            return f"lists a path outside its folder: {rel!r}"
        if not (isinstance(meta, dict) and isinstance(meta.get("bytes"), int) and isinstance(meta.get("sha256"), str)):
            return f"has no size and sha256 for {rel!r}"
    return None


def load_manifest(folder: str | Path) -> dict:
    """The folder's manifest; raises ManifestError saying what is wrong with it."""
    path = Path(folder) / MANIFEST
    if path.is_symlink() or not path.is_file():
        raise ManifestError(f"{path}: missing (the folder is not a complete seed)")
    if path.stat().st_size > MAX_MANIFEST_BYTES:
        raise ManifestError(f"{path}: {path.stat().st_size} bytes, too large to be a manifest")
    try:
        manifest = json.loads(path.read_bytes())
    except (OSError, ValueError, RecursionError) as exc:  # ValueError: bad UTF-8 or JSON, an integer too long
        raise ManifestError(f"{path}: unreadable ({exc.__class__.__name__})") from None
    problem = _schema_problem(manifest)
    if problem:
        raise ManifestError(f"{path}: {problem}")
    if CHECKSUM in manifest and manifest[CHECKSUM] != json_checksum({k: v for k, v in manifest.items() if k != CHECKSUM}):
        raise ManifestError(f"{path}: damaged (its contents differ from its own checksum)")
    return manifest


def read_manifest(folder: str | Path) -> dict | None:
    """The folder's manifest, or None if it has none or it is not a valid manifest."""
    try:
        return load_manifest(folder)
    except ManifestError:
        return None


def stage_count(manifest: dict) -> int:
    """Stages of the seed's timeline (``--phases``; 1 for an ordinary seed)."""
    config = manifest.get("config")
    phases = config.get("phases", 1) if isinstance(config, dict) else 1
    return phases if isinstance(phases, int) and phases > 1 else 1


def timeline_stage(folder: str | Path) -> tuple[Path, int] | None:
    """(the timeline seed folder, K) when ``folder`` is the ``phase_K`` folder of a timeline
    seed (whose manifest.json lies one level up), else None."""
    folder = Path(folder)
    match = re.fullmatch(r"phase_(\d+)", folder.name)
    if match and read_manifest(folder.parent) is not None:
        return folder.parent, int(match.group(1))
    return None


def seed_folder_containing(path: str | Path) -> Path | None:
    """The seed folder that ``path`` is or lies in (one with a manifest.json, even a damaged
    one, or being generated), if any: what nothing but the generator may write into. An
    unreadable folder on the way raises OSError."""
    path = Path(os.path.realpath(path))
    for folder in [path, *path.parents]:
        if (folder / MANIFEST).is_file() or (folder / PARTIAL_MARKER).is_file():
            return folder
    return None


@functools.lru_cache(maxsize=16)
def _listed_files(path: str, stamp: tuple) -> dict:
    """The file table of the manifest at ``path`` (cached while its ``stamp``: inode, size and
    modification time, is unchanged)."""
    return load_manifest(Path(path).parent)["files"]


def forget_manifests() -> None:
    """Drop the manifests :func:`listed_sha256` holds (the next call reads them again)."""
    _listed_files.cache_clear()


def listed_sha256(path: str | Path) -> str | None:
    """The sha256 that the manifest of the complete seed holding ``path`` lists for it; None
    when no complete seed holds it (a file elsewhere, or in a folder still being generated).
    A seed whose manifest is damaged or does not list the file raises ManifestError. Readers
    compare the bytes they read with it before trusting a file that carries no check of its
    own (JSON); the manifest is read once per process while it is unchanged."""
    path = Path(os.path.realpath(path))
    seed = seed_folder_containing(path.parent)
    if seed is None or not (seed / MANIFEST).is_file():
        return None
    st = (seed / MANIFEST).stat()
    files = _listed_files(str(seed / MANIFEST), (st.st_ino, st.st_size, st.st_mtime_ns))
    rel = path.relative_to(seed).as_posix()
    if rel not in files:
        raise ManifestError(f"{path}: not listed in the manifest of {seed}; the seed folder was changed, "
                            "check it with python -m generator verify")
    return files[rel]["sha256"]


def check_files(folder: str | Path, manifest: dict, hashes: bool | None = True) -> list[str]:
    """One line per file that differs from ``manifest``: missing, other size, other sha256,
    and every entry the manifest does not list (a file, a symlink, a FIFO, an empty folder;
    only the folder's own manifest.json and partial marker are not listed). ``hashes``: True
    hashes every file; False checks sizes only; None hashes the files whose modification time
    differs from the manifest's (a file written after the manifest, or copied without its
    times)."""
    folder = Path(folder)
    found: dict[str, str] = {}
    to_hash = []
    listed = manifest["files"]
    for rel, meta in listed.items():
        p = folder / rel
        if p.is_symlink() or not p.is_file():
            found[rel] = f"{rel}: missing"
            continue
        st = p.stat()
        if st.st_size != meta["bytes"]:
            found[rel] = f"{rel}: {st.st_size} bytes, the manifest says {meta['bytes']}"
        elif hashes or (hashes is None and st.st_mtime_ns != meta.get("mtime_ns")):
            to_hash.append(rel)
    for rel, digest in zip(to_hash, sha256_many([folder / rel for rel in to_hash])):
        if digest != listed[rel]["sha256"]:
            found[rel] = f"{rel}: contents changed (sha256 differs from the manifest)"
    problems = [found[rel] for rel in listed if rel in found]  # in the manifest's order
    files, others = _entries(folder)
    problems += [f"{rel}: not listed in the manifest" for rel in files if rel not in listed]
    problems += [f"{rel}: {what}, not listed in the manifest" for rel, what in others.items() if rel not in listed]
    return problems


def verify_manifest(folder: str | Path, hashes: bool = True) -> list[str]:
    """Problems found (a bad manifest, missing files, wrong sizes or hashes, unlisted files);
    empty if the folder is intact."""
    try:
        manifest = load_manifest(folder)
    except ManifestError as exc:
        return [str(exc)]
    return check_files(folder, manifest, hashes)
