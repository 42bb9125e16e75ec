"""The environment's on-disk cache of built sites (bpy-free): it replaces only entries it can
prove it made, and checks an entry's files against their hashes before every use.

An entry ``cache_dir/<name>/`` is built in a temporary folder ``cache_dir/.<name>-<12 hex>``
whose first file is the marker :data:`MARKER`; the build writes its files there, then the
marker is rewritten as the entry's record: the size and sha256 of every other file, and a
checksum of the record itself. Only then is the folder renamed ``<name>``, under the lock
file ``.<name>.lock`` (:func:`lock_path`). An existing entry is

- ours and intact: the marker, a record whose checksum holds, and exactly the files the
  record lists, with their sizes and hashes;
- ours and damaged: the marker and nothing the cache did not write, and either the record
  intact and a file that differs from it (or is missing), or the record's checksum broken
  and every file it lists intact: rebuilt, with a one-line :class:`SiteCacheWarning`;
- anything else (no marker, an unreadable record, a file or folder the record does not
  list, a link or a folder in place of one of its files; a link or a file in place of the
  entry): not ours, never renamed nor removed: :class:`ForeignEntry`.

A build killed midway leaves its temporary folder; the next use of the entry removes the
temporary folders of ``<name>`` that carry the marker, while it holds the entry's lock (so
never the folder of a build under way).
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import secrets
import shutil
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from exporters.manifest import json_checksum, sha256

MARKER = ".buildee-site-cache"  # written first into a build's folder; the entry's record at the end
SIGNATURE = "buildee-sites site cache"  # the marker's first key holds it
MAX_RECORD_BYTES = 1 << 20  # a record lists a few files: a larger marker is not ours


class ForeignEntry(ValueError):
    """A folder in the cache the cache did not make (one line: which, why, what to do)."""


class SiteCacheWarning(UserWarning):
    """A damaged entry of the cache is rebuilt (one line: which, what was wrong)."""


def lock_path(entry: Path) -> Path:
    """The lock file that every build or clean-up of ``entry`` holds."""
    return entry.parent / f".{entry.name}.lock"


def entry_state(entry: Path) -> tuple[str, str]:
    """('missing' | 'intact' | 'damaged', what is damaged) of the entry ``entry``; raises
    :class:`ForeignEntry` if the folder there is not one the cache can prove it made.
    Hashes every file of the entry."""
    if not os.path.lexists(entry):
        return "missing", ""
    if entry.is_symlink() or not entry.is_dir():
        _foreign(entry, "a link or a file, not a folder the cache built")
    try:
        names = set(os.listdir(entry))
    except OSError as exc:
        _foreign(entry, f"it cannot be listed: {exc.strerror or exc}")
    if MARKER not in names:
        _foreign(entry, f"no {MARKER} marker in it: not made by this cache, or by a version before markers")
    files, intact = _read_record(entry / MARKER)
    if files is None:
        _foreign(entry, f"its {MARKER} record is unreadable, so nothing proves the cache wrote its files")
    extra = sorted(names - set(files) - {MARKER})
    if extra:
        _foreign(entry, f"it holds {extra[0]!r}, which the cache did not write")
    odd = sorted(n for n in names if (entry / n).is_symlink() or not (entry / n).is_file())
    if odd:
        _foreign(entry, f"its {odd[0]!r} is a link or a folder, which the cache never writes")
    problems = _differences(entry, files)
    if problems and not intact:
        _foreign(entry, f"its {MARKER} record fails its checksum and {problems[0]}")
    if problems or not intact:
        return "damaged", problems[0] if problems else f"its {MARKER} record fails its checksum"
    return "intact", ""


def cached_entry(entry: Path, is_current: Callable[[Path], bool], build: Callable[[Path], None]) -> None:
    """Make ``entry`` an intact entry of ours that ``is_current`` accepts: kept if it is one,
    else built by ``build(folder)`` (which writes the entry's files into ``folder``) and put
    in place of a missing, stale or damaged entry of ours (a damaged one with a
    :class:`SiteCacheWarning`). A folder that is not ours raises :class:`ForeignEntry`."""
    state, _ = entry_state(entry)
    if state == "intact" and is_current(entry):
        if _leftovers(entry):
            _remove_leftovers_if_free(entry)
        return
    with _locked(entry):
        remove_leftovers(entry)
        state, problem = entry_state(entry)  # another process may have built it while we waited
        if state == "intact" and is_current(entry):
            return
        if state == "damaged":
            warnings.warn(f"{entry}: the cached site is damaged ({problem}); rebuilding it", SiteCacheWarning,
                          stacklevel=3)
        _build_in_place(entry, build)


def remove_leftovers(entry: Path) -> list[Path]:
    """Remove the temporary folders of killed builds of ``entry`` (``.<name>-<12 hex>`` and
    ``.<name>-<12 hex>-old`` folders carrying the marker); call it holding :func:`lock_path`.
    Returns them."""
    removed = [p for p in _leftovers(entry) if _carries_marker(p)]
    for p in removed:
        shutil.rmtree(p, ignore_errors=True)
    return removed


# ---- records ------------------------------------------------------------------------------
def _readable_sha256(path: Path) -> str | None:
    try:
        return sha256(path)
    except OSError:
        return None


def _seal(folder: Path) -> None:
    """Rewrite the marker of a finished build as the record of every other file in ``folder``."""
    files = {}
    for name in sorted(os.listdir(folder)):
        path = folder / name
        if name == MARKER:
            continue
        if path.is_symlink() or not path.is_file():
            raise RuntimeError(f"the site build wrote {path}, not a regular file; the cache holds files only")
        files[name] = {"bytes": path.stat().st_size, "sha256": sha256(path)}
    text = json.dumps({"written_by": SIGNATURE, "files": files, "checksum": json_checksum(files)}, indent=1)
    tmp = folder / f"{MARKER}.tmp"
    tmp.write_text(text)
    os.replace(tmp, folder / MARKER)  # a build killed here leaves a marker either way


def _read_record(marker: Path) -> tuple[dict | None, bool]:
    """(files listed by the record ``marker``, None if unreadable; whether its checksum holds)."""
    try:
        if marker.is_symlink() or marker.stat().st_size > MAX_RECORD_BYTES:
            return None, False
        record = json.loads(marker.read_bytes())
    except (OSError, ValueError):
        return None, False
    files = record.get("files") if isinstance(record, dict) and record.get("written_by") == SIGNATURE else None
    if not isinstance(files, dict) or not all(_well_formed(name, meta) for name, meta in files.items()):
        return None, False
    return files, record.get("checksum") == json_checksum(files)


def _well_formed(name, meta) -> bool:
    return (isinstance(name, str) and name not in ("", ".", "..", MARKER) and "/" not in name and "\0" not in name
            and isinstance(meta, dict) and type(meta.get("bytes")) is int and isinstance(meta.get("sha256"), str))


def _differences(entry: Path, files: dict) -> list[str]:
    problems = []
    for name, meta in files.items():
        path = entry / name
        if path.is_symlink() or not path.is_file():
            problems.append(f"{name} is missing")
        elif path.stat().st_size != meta["bytes"]:
            problems.append(f"{name} has {path.stat().st_size} bytes, the record says {meta['bytes']}")
        elif _readable_sha256(path) != meta["sha256"]:
            problems.append(f"{name} differs from its recorded sha256 (or cannot be read)")
    return problems


def _foreign(entry: Path, why: str):
    raise ForeignEntry(f"cache_dir holds {entry}, which the site cache did not make ({why}); it is left untouched: "
                       "move it away, or pass another cache_dir")


# ---- building, locking, leftovers ------------------------------------------------------------
def _build_in_place(entry: Path, build: Callable[[Path], None]) -> None:
    """Build into a new temporary folder (marker first), seal it, and rename it ``entry``
    (an entry already there is ours: the caller checked it under the lock)."""
    while True:
        tmp = entry.parent / f".{entry.name}-{secrets.token_hex(6)}"
        try:
            tmp.mkdir()
            break
        except FileExistsError:
            continue
    old = entry.parent / f"{tmp.name}-old"
    try:
        (tmp / MARKER).write_text(json.dumps({"written_by": SIGNATURE, "files": None}))
        build(tmp)
        _seal(tmp)
        if os.path.lexists(entry):
            os.rename(entry, old)
        os.rename(tmp, entry)
    finally:
        for leftover in (tmp, old):
            if leftover.is_dir() and not leftover.is_symlink():
                shutil.rmtree(leftover, ignore_errors=True)


@contextmanager
def _locked(entry: Path, blocking: bool = True):
    """Hold the entry's lock (yields False if ``blocking`` is False and another process holds it)."""
    path = lock_path(entry)
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)  # never truncates: a user's file there stays whole
    except OSError as exc:
        raise ValueError(f"cache_dir: cannot lock {path} ({exc.strerror or exc}); pass a writable cache_dir, "
                         "or move that file away") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
        except BlockingIOError:
            yield False
            return
        yield True
    finally:
        os.close(fd)


def _leftovers(entry: Path) -> list[Path]:
    pattern = re.compile(rf"\.{re.escape(entry.name)}-[0-9a-f]{{12}}(-old)?")
    try:
        names = os.listdir(entry.parent)
    except OSError:
        return []
    return [entry.parent / n for n in sorted(names) if pattern.fullmatch(n)]


def _carries_marker(folder: Path) -> bool:
    marker = folder / MARKER
    try:
        if folder.is_symlink() or marker.is_symlink() or marker.stat().st_size > MAX_RECORD_BYTES:
            return False
        record = json.loads(marker.read_bytes())
    except (OSError, ValueError):
        return False
    return isinstance(record, dict) and record.get("written_by") == SIGNATURE


def _remove_leftovers_if_free(entry: Path) -> None:
    with _locked(entry, blocking=False) as held:
        if held:
            remove_leftovers(entry)
