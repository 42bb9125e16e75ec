"""A seed's place in the output folder: its lock, what is already there, its partial folder
and the commit that makes it complete. bpy-free.

    seed_NNNNNN/            a complete seed: our manifest.json lists every file in it
    .seed_NNNNNN.partial/   a seed being written; its first file is the marker PARTIAL_MARKER
    .seed_NNNNNN.lock       the seed's lock file (fcntl.flock), removed by the run that held it
    .seed_NNNNNN.work.lock  held by the process making the seed and its worker process (on
                            whichever node): a new attempt waits for it before it touches
                            the partial folder

Nothing here deletes a path that is not provably ours: a partial folder with our marker
(and only while we hold the seed's lock), or a complete seed the user asked to replace."""

from __future__ import annotations

import ctypes
import errno
import fcntl
import json
import os
import shutil
import socket
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from exporters import FORMAT_VERSION
from exporters.manifest import PARTIAL_MARKER, ManifestError, check_files, load_manifest

from .config import IMPLIED_CONFIG, canonical_config


def seed_folder(out: Path, seed: int) -> Path:
    return out / f"seed_{seed:06d}"


def partial_folder(out: Path, seed: int) -> Path:
    return out / f".seed_{seed:06d}.partial"


DISK_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO)  # the disk refuses: nothing in the way


def write_failure(exc: OSError, what: str) -> tuple[str, str]:
    """(status, message) of a seed whose ``what`` could not be made: 'failed' (exit code 1)
    when the disk refuses to write (full, over quota, read-only, I/O error), 'conflict' (exit
    code 3, something in the way that the user made) otherwise."""
    reason = exc.strerror or str(exc)
    if exc.errno in DISK_ERRNOS:
        return "failed", f"cannot write {what}: {reason}; free space on the disk or choose another --out, then rerun"
    return "conflict", f"cannot write {what}: {reason}; move it away if you made it"


def lock_file(out: Path, seed: int) -> Path:
    return out / f".seed_{seed:06d}.lock"


def work_lock_file(out: Path, seed: int) -> Path:
    return out / f".seed_{seed:06d}.work.lock"


def replaced_folder(out: Path, seed: int) -> Path:
    return out / f".seed_{seed:06d}.replaced"


class SeedLock:
    """An exclusive ``flock`` on the seed's lock file. The kernel releases it when every
    process holding the descriptor (the runner and its worker) has exited, so a killed run
    never leaves a lock that blocks."""

    def __init__(self, path: Path, fd: int):
        self.path, self.fd = path, fd

    @classmethod
    def try_acquire(cls, out: Path, seed: int) -> "SeedLock | None":
        """The lock, or None while another process holds it. OSError if the lock file's name
        is taken by something else (a folder, a symlink)."""
        return cls._try(lock_file(out, seed), f"{os.getpid()}")

    @classmethod
    def wait_for_work(cls, out: Path, seed: int, seconds: float,
                      cancelled: threading.Event | None = None) -> "SeedLock | None":
        """The seed's work lock, waiting up to ``seconds`` while a process of an earlier
        attempt still holds it (a worker that outlives its run: Ray kills a task's processes
        1-3 s after its driver is killed with SIGKILL, and the driver's own lock is released at
        once); None if it is still held then, or once ``cancelled`` is set. The file names its
        holder: 'host H pid P' (the holder may be on another node). OSError as
        :meth:`try_acquire`."""
        deadline = time.monotonic() + seconds
        cancelled = cancelled or threading.Event()
        while True:
            lock = cls._try(work_lock_file(out, seed), f"host {socket.gethostname()} pid {os.getpid()}")
            if lock is not None or time.monotonic() >= deadline or cancelled.wait(0.05):
                return lock

    @classmethod
    def _try(cls, path: Path, holder: str) -> "SeedLock | None":
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                return None
            try:
                same = os.stat(path, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:  # not a file its previous holder unlinked after we opened it
                os.ftruncate(fd, 0)
                os.write(fd, f"{holder}\n".encode())
                return cls(path, fd)
            os.close(fd)

    def release(self) -> None:
        """Remove the lock file, then let go (others recheck the file they locked)."""
        if self.fd < 0:
            return
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        os.close(self.fd)
        self.fd = -1


def lock_holder(out: Path, seed: int) -> str:
    """The process id written by the run holding the seed's lock ('' if unknown)."""
    try:
        return lock_file(out, seed).read_text()[:20].strip()
    except (OSError, UnicodeDecodeError):
        return ""


@dataclass
class Decision:
    """What to do with one seed: ``action`` is 'run' (generate it), 'skip' (complete and
    intact), 'conflict' (something in the way is left alone) or 'corrupt' (a complete seed
    whose files differ from its manifest, left alone); ``replace`` says a complete seed
    is to be replaced once the new one is committed."""

    action: str
    message: str
    replace: bool = False
    summary: dict | None = None


def _differences(old: dict, new: dict) -> str:
    keys = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    shown = {k: (old.get(k, IMPLIED_CONFIG.get(k)), new.get(k, IMPLIED_CONFIG.get(k))) for k in keys[:3]}
    return ", ".join(f"{k} {a!r} (now {b!r})" for k, (a, b) in shown.items()) + (" ..." if len(keys) > 3 else "")


def decide(out: Path, seed: int, config: dict, overwrite: bool, repair: bool, hashes: bool | None) -> Decision:
    """What to do with ``seed`` given what ``out`` holds; call it holding the seed's lock.
    ``config``: RunConfig.to_dict(). ``hashes`` as in ``exporters.manifest.check_files`` (True
    with --verify or --repair)."""
    final = seed_folder(out, seed)
    if not os.path.lexists(final):
        return Decision("run", "")
    if final.is_symlink() or not final.is_dir():
        return Decision("conflict", f"{final.name} in {out} is a {'symlink' if final.is_symlink() else 'file'}, "
                                    "not a seed folder; left alone: move it away or choose another --out")
    try:
        manifest = load_manifest(final)
    except ManifestError as exc:
        what = "not a seed folder written by this tool" if not (final / "manifest.json").exists() else str(exc)
        return Decision("conflict", f"{final}: {what}; left alone: move it away or choose another --out")
    if overwrite:
        return Decision("run", "replacing the complete seed (--overwrite)", replace=True)
    stored = canonical_config(manifest["config"])
    if manifest["format_version"] != FORMAT_VERSION or stored != config or manifest["seed"] != seed:
        old = {"format_version": manifest["format_version"], "seed": manifest["seed"], **stored}
        new = {"format_version": FORMAT_VERSION, "seed": seed, **config}
        return Decision("conflict", f"complete with other parameters: {_differences(old, new)}; left alone: "
                                    "use --overwrite to replace it, or another --out")
    problems = check_files(final, manifest, hashes)
    if problems:
        if repair:
            return Decision("run", f"redoing it ({problems[0]})", replace=True)
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        return Decision("corrupt", f"complete but {problems[0]}{more}; left alone: rerun with --repair to redo it")
    checked = "sizes and sha256 checked" if hashes else "sizes checked"
    return Decision("skip", f"already complete ({checked}), skipped", summary=manifest.get("summary", {}))


def start_partial(out: Path, seed: int) -> tuple[Path, str]:
    """A fresh, marked partial folder for ``seed`` (hold its lock): removes a partial folder
    of an earlier run if it carries our marker. Returns (folder, note); OSError if the
    partial folder's name is taken by something that is not ours."""
    partial = partial_folder(out, seed)
    note = "unfinished output from an earlier run removed; redoing it" if drop_partial(out, seed) else ""
    _drop_replaced(out, seed)
    partial.mkdir()
    (partial / PARTIAL_MARKER).write_text(json.dumps({"seed": seed, "pid": os.getpid()}))
    return partial, note


def drop_idle_partial(out: Path, seed: int, wait: float = 0.0) -> None:
    """Hold the seed's lock. Remove an earlier attempt's partial folder of ``seed`` and its work
    lock file once no process holds that lock (waiting up to ``wait`` seconds; else leave
    both: a later run waits for it); anything not ours is left alone."""
    try:
        work = SeedLock.wait_for_work(out, seed, wait)
    except OSError:
        return
    if work is None:
        return
    try:
        drop_partial(out, seed)
    except OSError:
        pass
    finally:
        work.release()


def drop_partial(out: Path, seed: int) -> bool:
    """Hold the seed's lock. Remove an earlier run's partial folder of ``seed`` (True if there
    was one); OSError if something not ours has its name."""
    partial = partial_folder(out, seed)
    if not os.path.lexists(partial):
        return False
    marker = partial / PARTIAL_MARKER
    if partial.is_symlink() or not partial.is_dir() or marker.is_symlink() or not marker.is_file():
        raise OSError(errno.EEXIST, f"{partial} exists and was not made by this tool; move it away")
    shutil.rmtree(partial)
    return True


def restore_replaced(out: Path, seed: int) -> str:
    """Hold the seed's lock. A replacement interrupted between its two renames left the old
    complete seed aside and no seed folder: put it back. Returns a note ('' if nothing)."""
    old, final = replaced_folder(out, seed), seed_folder(out, seed)
    if os.path.lexists(final) or old.is_symlink() or not old.is_dir():
        return ""
    try:
        load_manifest(old)
    except ManifestError:
        return ""
    rename_no_replace(old, final)
    return f"the complete seed an interrupted replacement had set aside ({old.name}) was put back"


def _drop_replaced(out: Path, seed: int) -> None:
    """Remove a complete seed an interrupted replacement left aside (ours: it has our manifest)."""
    old = replaced_folder(out, seed)
    if old.is_dir() and not old.is_symlink():
        try:
            load_manifest(old)
        except ManifestError:
            return
        shutil.rmtree(old)


def commit(out: Path, seed: int, config: dict, replace: bool) -> str:
    """Make the partial folder ``seed``'s complete folder, atomically; hold the seed's lock
    and call it once the worker has exited (every file closed). Checks first that the
    manifest is ours, for this seed and ``config``, and that every file it lists is there
    with its size and nothing else is. Returns '' or the reason nothing was committed."""
    partial, final = partial_folder(out, seed), seed_folder(out, seed)
    try:
        manifest = load_manifest(partial)
    except ManifestError as exc:
        return str(exc)
    if manifest["seed"] != seed or manifest["config"] != config:
        return f"{partial}: the manifest is for another seed or configuration"
    problems = check_files(partial, manifest, hashes=False)
    if problems:
        return f"{partial}: {problems[0]}" + (f" (and {len(problems) - 1} more)" if len(problems) > 1 else "")
    if replace and os.path.lexists(final):
        rename_no_replace(final, replaced_folder(out, seed))
    try:
        rename_no_replace(partial, final)
    except OSError as exc:
        if replace and os.path.lexists(replaced_folder(out, seed)):
            os.rename(replaced_folder(out, seed), final)
        return f"could not move {partial.name} to {final.name}: {exc.strerror}"
    (final / PARTIAL_MARKER).unlink(missing_ok=True)
    return ""


def drop_replaced(out: Path, seed: int) -> str:
    """After a committed replacement: delete the old seed it set aside. The new seed is
    complete either way; returns '' or a note saying what is left to delete by hand."""
    try:
        _drop_replaced(out, seed)
    except OSError as exc:
        return (f"the old seed set aside in {replaced_folder(out, seed)} could not be deleted "
                f"({exc.filename}: {exc.strerror}); delete that folder by hand")
    return ""


def leftover_replaced(out: Path, seed: int) -> str:
    """'' or why ``seed`` cannot be replaced now: a partly deleted old seed (no manifest any
    more) is still set aside from an earlier replacement."""
    old = replaced_folder(out, seed)
    if os.path.lexists(old) and os.path.lexists(seed_folder(out, seed)):
        return f"{old} is left from an earlier replacement whose deletion failed; delete it, then rerun"
    return ""


_libc = ctypes.CDLL(None, use_errno=True)
_RENAME_NOREPLACE = 1


def rename_no_replace(src: Path, dst: Path) -> None:
    """rename(2) that fails with EEXIST instead of replacing ``dst`` (even an empty folder)."""
    renameat2 = getattr(_libc, "renameat2", None)
    if renameat2 is None:  # C library without renameat2: check, then rename
        if os.path.lexists(dst):
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
        os.rename(src, dst)
        return
    AT_FDCWD = -100
    if renameat2(AT_FDCWD, os.fsencode(src), AT_FDCWD, os.fsencode(dst), _RENAME_NOREPLACE) != 0:
        e = ctypes.get_errno()
        raise OSError(e, os.strerror(e), str(dst))
