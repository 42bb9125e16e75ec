"""A seed's work, the one function every executor runs: a fresh, marked partial folder,
one fresh worker process (``python -m generator.batch.worker``: build, fly, write the
files, manifest last), its progress events forwarded as they come, then the checked,
atomic commit (``folders.commit``). The local executor calls it in a thread of the
runner; the Ray executor in a Ray task on whichever node runs the seed. bpy-free.

Call it holding the seed's lock (the runner takes it before submitting)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from .. import folders

# the pid of the process that starts a worker, so that the worker can tell it was orphaned
# before it could ask to die with it (generator/batch/worker.py)
PARENT_ENV = "BUILDEE_WORKER_PARENT"
# seconds an attempt waits for the worker of an earlier one to be gone (folders.SeedLock.wait_for_work)
WORK_LOCK_WAIT = 120.0  # more than NFSv4's 90 s lease, after which a dead node's locks are released
# seconds a cancelled seed's partial folder waits for its worker to let go of the work lock
# before it is removed (folders.drop_idle_partial; else it is left for the next run)
CANCEL_WAIT = 5.0

ROOT = Path(__file__).resolve().parents[3]  # the worker runs with the repository as its working folder


@dataclass(frozen=True)
class SeedJob:
    """What to make: ``seed`` with ``config`` (RunConfig.to_dict()) into ``out`` (an absolute
    path every node sees); ``replace``: a complete seed there is replaced on commit;
    ``lock_fd``: the seed's lock descriptor, shared with the worker process (local only);
    ``env``: variables added to the worker's environment; ``executor``: the name of the
    executor that runs it, recorded in the manifest's timing (how this run went, not a
    parameter: the seed's files are the same on every executor)."""

    seed: int
    out: str
    config: dict
    replace: bool = False
    lock_fd: int | None = None
    env: dict = field(default_factory=dict)
    executor: str = ""


@dataclass
class Outcome:
    """How one attempt at a seed ended. ``status``: 'done' (committed), 'failed' (also when
    a process of an earlier attempt still holds the seed's work lock) or 'conflict' (its
    partial folder's or work lock's name is taken by something not ours); ``lost``: the
    worker process was killed by a signal (a crash, the OOM killer, a kill), so another
    attempt may succeed; ``note``: what was found and removed before starting."""

    seed: int
    status: str
    message: str = ""
    summary: dict = field(default_factory=dict)
    seconds: float = 0.0
    lost: bool = False
    note: str = ""
    node: str = ""  # where it ran, when not on this machine (the node's address)


Emit = Callable[[dict], None]


def produce_seed(job: SeedJob, emit: Emit, started: Callable[[subprocess.Popen], None] | None = None,
                 cancelled: threading.Event | None = None) -> Outcome:
    """Make ``job.seed`` in a partial folder of ``job.out`` and commit it. ``emit`` receives
    the seed's progress events as they happen: {"event": "note", "message"} (something of an
    earlier run was removed), {"event": "start", "frames"} (frames to render) and
    {"event": "frame"} (one more frame written). ``started`` receives the worker process
    (to cancel it: kill its process group), once the partial folder is made. ``cancelled``,
    once set, ends the wait for the work lock: nothing is touched."""
    out = Path(job.out).absolute()  # the worker runs in the repository's folder
    work_path = folders.work_lock_file(out, job.seed)
    try:
        work = folders.SeedLock.wait_for_work(out, job.seed, WORK_LOCK_WAIT, cancelled)
    except OSError as exc:
        return Outcome(job.seed, *folders.write_failure(exc, f"the work lock {work_path}"))
    if cancelled is not None and cancelled.is_set():
        if work is not None:
            work.release()
        return Outcome(job.seed, "failed", "cancelled")
    if work is None:
        return Outcome(job.seed, "failed", f"a process of an earlier attempt ({_holder(work_path)}) still holds "
                       f"{work_path} after {WORK_LOCK_WAIT:g} s; its partial folder is left alone: run again once "
                       "that process has stopped (on a network file system, once a dead node's lock has expired)")
    try:
        return _produce(job, emit, started, out, time.perf_counter(), work)
    finally:
        work.release()


def _holder(path: Path) -> str:
    """'host H pid P' as the work lock's holder wrote it."""
    try:
        return path.read_text()[:200].strip() or "unknown"
    except (OSError, UnicodeDecodeError):
        return "unknown"


def _produce(job: SeedJob, emit: Emit, started, out: Path, t0: float, work: folders.SeedLock) -> Outcome:
    """produce_seed holding the seed's work lock, which the worker process shares."""
    try:
        folder, note = folders.start_partial(out, job.seed)
    except OSError as exc:  # the disk refuses (exit code 1), or a folder not ours has its name (left alone)
        if exc.errno in folders.DISK_ERRNOS:
            return Outcome(job.seed, *folders.write_failure(exc, f"the partial folder of seed {job.seed} in {out}"))
        return Outcome(job.seed, "conflict", exc.strerror or str(exc))
    if note:
        emit({"event": "note", "message": note})
    env = {k: v for k, v in os.environ.items() if k != "OCIO"} | job.env | {PARENT_ENV: str(os.getpid())}
    proc = subprocess.Popen(
        [sys.executable, "-m", "generator.batch.worker", json.dumps(job.config), str(job.seed), str(folder),
         job.executor],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, start_new_session=True, cwd=ROOT,
        pass_fds=(work.fd,) if job.lock_fd is None else (work.fd, job.lock_fd))
    try:
        if started:
            started(proc)
        code, errors, done, stderr = _follow(proc, emit)
    finally:  # however this ends (an exception, Ray's SIGTERM): no worker outlives the work lock
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    seconds = time.perf_counter() - t0
    if code == 0 and done is not None:
        try:
            problem = folders.commit(out, job.seed, job.config, job.replace)
        except OSError as exc:
            problem = f"{exc.filename or folder}: {exc.strerror}"
        if not problem:
            left = folders.drop_replaced(out, job.seed) if job.replace else ""
            if left:  # the new seed is committed all the same
                emit({"event": "note", "message": left})
            return Outcome(job.seed, "done", "", done, seconds, note=note)
        return Outcome(job.seed, "failed", f"not committed: {problem}", {}, seconds, note=note)
    return Outcome(job.seed, "failed", _cause(code, errors, stderr, folder), {}, seconds, lost=code < 0,
                   note=note)


def _follow(proc: subprocess.Popen, emit: Emit) -> tuple[int, list[str], dict | None, str]:
    """Forward the worker's progress events until it exits: (exit code, error messages, its
    summary if it finished, its stderr)."""
    stderr: list[str] = []
    reader = threading.Thread(target=lambda: stderr.append(proc.stderr.read()), daemon=True)
    reader.start()
    errors, done = [], None
    for line in proc.stdout:
        if not line.startswith("@@"):
            continue
        event = json.loads(line[2:])
        if event["event"] == "frame":
            emit({"event": "frame"})
        elif event["event"] == "start":
            emit({"event": "start", "frames": event["frames"]})
        elif event["event"] == "error":
            errors.append(event["message"])
        elif event["event"] == "done":
            done = event["summary"]
    code = proc.wait()
    reader.join()
    return code, errors, done, "".join(stderr)


def _cause(code: int, errors: list[str], stderr: str, folder: Path) -> str:
    """One line saying why the worker failed, and where its traceback is."""
    if errors:
        cause = errors[0]
    elif code < 0:
        cause = f"worker process killed by {signal.Signals(-code).name}" + \
            (" (out of memory?)" if code == -signal.SIGKILL else "")
    else:
        cause = (stderr.strip().splitlines() or [f"exit code {code}"])[-1]
    log = folder / "error.log"
    return cause + (f" (details: {log})" if log.exists() else "")
