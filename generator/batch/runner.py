"""Run seeds in worker processes, one writer per seed: each seed is locked, checked against
what the output folder holds (generation.folders.decide), written into a marked partial
folder by its worker and committed atomically. bpy-free (workers import it)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from . import folders
from .config import RunConfig

# exit codes of python -m generator (docs/guarantees.md); the most severe applies
EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_LEFT_ALONE, EXIT_BUSY = 0, 1, 2, 3, 4
_EXIT_OF = {"done": EXIT_OK, "skipped": EXIT_OK, "failed": EXIT_FAILED, "conflict": EXIT_LEFT_ALONE,
            "corrupt": EXIT_LEFT_ALONE, "busy": EXIT_BUSY}


@dataclass
class SeedResult:
    seed: int
    status: str  # done, skipped, failed, conflict, corrupt, busy
    message: str = ""
    summary: dict = field(default_factory=dict)
    seconds: float = 0.0


@dataclass(frozen=True)
class Options:
    """overwrite: replace complete seeds; repair: redo complete seeds whose files fail the
    check; hashes: True hashes every file of a complete seed, None only files whose time
    changed; wait: wait for seeds another run is writing instead of skipping them."""

    overwrite: bool = False
    repair: bool = False
    hashes: bool | None = None
    wait: bool = False
    workers: int = 1


def exit_code(results: list[SeedResult]) -> int:
    codes = {_EXIT_OF[r.status] for r in results}
    return next((c for c in (EXIT_FAILED, EXIT_LEFT_ALONE, EXIT_BUSY) if c in codes), EXIT_OK)


class _Worker:
    """One seed's worker process; it shares the seed's lock descriptor with the runner."""

    def __init__(self, seed: int, out: Path, cfg: RunConfig, position: int, lock: folders.SeedLock,
                 replace: bool, bar_lock):
        self.seed, self.out, self.cfg, self.lock, self.replace, self.bar_lock = seed, out, cfg, lock, replace, bar_lock
        self.folder, self.note = folders.start_partial(out, seed)
        self.position = position
        env = {k: v for k, v in os.environ.items() if k != "OCIO"}
        self.start_time = time.perf_counter()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "generator.batch.worker", json.dumps(cfg.to_dict()), str(seed), str(self.folder)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, start_new_session=True,
            cwd=Path(__file__).resolve().parents[2], pass_fds=(lock.fd,))
        self.bar = tqdm(total=cfg.frames * len(cfg.trajectories), desc=f"seed {seed} frames", unit="frame",
                        position=position, leave=False, dynamic_ncols=True)
        self.events: list[dict] = []
        self.stderr = ""
        self.readers = [threading.Thread(target=self._read, daemon=True), threading.Thread(target=self._read_err, daemon=True)]
        for t in self.readers:
            t.start()

    def _read(self):
        for line in self.proc.stdout:
            if line.startswith("@@"):
                event = json.loads(line[2:])
                self.events.append(event)
                if event["event"] == "frame":
                    with self.bar_lock:
                        self.bar.update(1)

    def _read_err(self):
        self.stderr = self.proc.stderr.read()

    def finish(self) -> SeedResult:
        """Commit the seed if its worker succeeded, then release its lock."""
        for t in self.readers:
            t.join()
        self.bar.close()
        seconds = time.perf_counter() - self.start_time
        done = [e for e in self.events if e["event"] == "done"]
        try:
            if self.proc.returncode == 0 and done:
                try:
                    problem = folders.commit(self.out, self.seed, self.cfg.to_dict(), self.replace)
                except OSError as exc:
                    problem = f"{exc.filename or self.folder}: {exc.strerror}"
                if not problem:
                    return SeedResult(self.seed, "done", "", done[0]["summary"], seconds)
                return SeedResult(self.seed, "failed", f"not committed: {problem}", {}, seconds)
            return SeedResult(self.seed, "failed", self._cause(), {}, seconds)
        finally:
            self.lock.release()

    def _cause(self) -> str:
        errors = [e["message"] for e in self.events if e["event"] == "error"]
        code = self.proc.returncode
        ended = f"killed by {signal.Signals(-code).name}" + (" (out of memory?)" if code == -signal.SIGKILL else "") \
            if code < 0 else f"exit code {code}"
        cause = errors[0] if errors else (self.stderr.strip().splitlines() or [ended])[-1]
        log = self.folder / "error.log"
        return cause + (f" (details: {log})" if log.exists() else "")

    def abandon(self):
        """Interrupted: kill the worker, remove its partial folder (made by this run), unlock."""
        try:
            os.killpg(self.proc.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        self.proc.wait()
        shutil.rmtree(self.folder, ignore_errors=True)
        self.lock.release()


def _claim(out: Path, seed: int, cfg: RunConfig, opts: Options) -> tuple[folders.SeedLock | None, SeedResult | None, folders.Decision | None]:
    """(lock, None, decision) when ``seed`` is to be generated; (None, result, None) when it
    is settled without work; (None, None, None) while another run holds it and we wait."""
    try:
        lock = folders.SeedLock.try_acquire(out, seed)
    except OSError as exc:
        return None, SeedResult(seed, "conflict", f"cannot lock with lock file {folders.lock_file(out, seed)}: "
                                                  f"{exc.strerror}; move it away if you made it (a file system "
                                                  "without flock needs a local --out)"), None
    if lock is None:
        if opts.wait:
            return None, None, None
        pid = folders.lock_holder(out, seed)
        return None, SeedResult(seed, "busy", f"being written by another run{f' (pid {pid})' if pid else ''}; "
                                              "skipped: rerun later, or add --wait"), None
    try:
        restored = folders.restore_replaced(out, seed)
        if restored:
            tqdm.write(f"seed {seed}: {restored}")
        d = folders.decide(out, seed, cfg.to_dict(), opts.overwrite, opts.repair, True if opts.hashes else None)
    except OSError as exc:
        lock.release()
        return None, SeedResult(seed, "conflict", f"cannot check {exc.filename or out}: {exc.strerror}; left alone"), None
    if d.action == "run":
        return lock, None, d
    if d.action == "skip":
        try:
            folders.drop_partial(out, seed)  # debris of an earlier run, if ours
        except OSError:
            pass
    lock.release()
    return None, SeedResult(seed, "skipped" if d.action == "skip" else d.action, d.message, d.summary or {}), None


def run_seeds(out: Path, seeds: list[int], cfg: RunConfig, opts: Options) -> list[SeedResult]:
    """Run ``seeds`` with up to ``opts.workers`` processes at once; returns their results."""
    bar_lock = threading.Lock()
    results: list[SeedResult] = []
    pending = list(seeds)
    running: list[_Worker] = []
    announced: set[int] = set()
    overall = tqdm(total=len(seeds), desc="seeds", unit="seed", position=0, dynamic_ncols=True)

    def report(r: SeedResult):
        results.append(r)
        overall.update(1)
        tqdm.write(one_line(r))

    try:
        while pending or running:
            waiting = []
            while pending and len(running) < opts.workers:
                seed = pending.pop(0)
                lock, settled, decision = _claim(out, seed, cfg, opts)
                if settled:
                    report(settled)
                elif lock is None:
                    waiting.append(seed)
                    if seed not in announced:
                        announced.add(seed)
                        tqdm.write(f"seed {seed}: being written by another run; waiting (--wait)")
                elif w := _start(seed, out, cfg, lock, decision, running, bar_lock, report):
                    running.append(w)
            pending = waiting + pending
            time.sleep(0.2)
            for w in [w for w in running if w.proc.poll() is not None]:
                running.remove(w)
                report(w.finish())
    except KeyboardInterrupt:
        for w in running:
            w.abandon()
        overall.close()
        raise
    overall.close()
    return results


def _start(seed, out, cfg, lock, decision, running, bar_lock, report) -> "_Worker | None":
    """The seed's worker, started; or None (reported, unlocked) if its partial folder is taken."""
    position = min(p for p in range(1, len(running) + 2) if p not in {w.position for w in running})
    try:
        w = _Worker(seed, out, cfg, position, lock, decision.replace, bar_lock)
    except OSError as exc:
        lock.release()
        report(SeedResult(seed, "conflict", exc.strerror or str(exc)))
        return None
    for note in (w.note, decision.message):
        if note:
            tqdm.write(f"seed {seed}: {note}")
    return w


def one_line(r: SeedResult) -> str:
    if r.status == "failed":
        return f"seed {r.seed}: FAILED after {r.seconds:.0f} s: {r.message}"
    if r.status != "done":
        return f"seed {r.seed}: {r.message}"
    s = r.summary
    return (f"seed {r.seed}: {s.get('frames', 0)} frames, {s.get('points', 0):,} points, "
            f"{s.get('visible_tracks', 0):,} visible tracks, {r.seconds:.0f} s")
