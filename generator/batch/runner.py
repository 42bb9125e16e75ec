"""Run seeds, one writer per seed: each seed is locked and checked against what the output
folder holds (folders.decide) here, then computed by an executor (executors/: local worker
processes or Ray tasks; both run executors.seed.produce_seed: a marked partial folder, a
fresh worker process, the atomic commit), whose events feed the progress bars. bpy-free."""

from __future__ import annotations

import signal
import threading
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from . import folders
from .config import RunConfig
from .executors import Executor, Outcome, SeedJob

# exit codes of python -m generator (docs/guarantees.md); the most severe applies
EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_LEFT_ALONE, EXIT_BUSY = 0, 1, 2, 3, 4
INTERRUPTED = threading.Event()  # set by interrupt(); the run loop stops at its next turn
SIGNALS: list[int] = []  # the signals interrupt() was called for, in order


def interrupt(signum=None, frame=None) -> None:
    """Signal handler for Ctrl-C and SIGTERM: raise KeyboardInterrupt, and remember it, so that
    a library that catches the exception inside a blocking call (Ray's waits check signals
    from C++) cannot make the run go on: the run loop raises it again at its next turn."""
    SIGNALS.append(signal.SIGINT if signum is None else signum)
    if INTERRUPTED.is_set() and len(SIGNALS) > 1:
        return  # the clean-up of the first signal is under way: a second one must not cut it short
    INTERRUPTED.set()
    raise KeyboardInterrupt


def stopped_by() -> tuple[int, str]:
    """(exit code, word) of the first signal that stopped the run (later ones during the
    clean-up are noted, not acted on): 130 "interrupted" (Ctrl-C), 143 "terminated (SIGTERM)"."""
    if SIGNALS and SIGNALS[0] == signal.SIGTERM:
        return 128 + signal.SIGTERM, "terminated (SIGTERM)"
    return 128 + signal.SIGINT, "interrupted"


_EXIT_OF = {"done": EXIT_OK, "skipped": EXIT_OK, "failed": EXIT_FAILED, "conflict": EXIT_LEFT_ALONE,
            "corrupt": EXIT_LEFT_ALONE, "busy": EXIT_BUSY}


@dataclass
class SeedResult:
    seed: int
    status: str  # done, skipped, failed, conflict, corrupt, busy
    message: str = ""
    summary: dict = field(default_factory=dict)
    seconds: float = 0.0
    attempts: int = 1  # attempts at computing it (more than 1: its worker was lost and the executor retried)
    node: str = ""  # the cluster node that computed it ('' on this machine)


@dataclass(frozen=True)
class Options:
    """overwrite: replace complete seeds; repair: redo complete seeds whose files fail the
    check; hashes (True with --verify or --repair): True hashes every file of a complete seed, None only files whose time
    changed; wait: wait for seeds another run is writing instead of skipping them."""

    overwrite: bool = False
    repair: bool = False
    hashes: bool | None = None
    wait: bool = False
    workers: int = 1


def exit_code(results: list[SeedResult]) -> int:
    codes = {_EXIT_OF[r.status] for r in results}
    return next((c for c in (EXIT_FAILED, EXIT_LEFT_ALONE, EXIT_BUSY) if c in codes), EXIT_OK)


def _claim(out: Path, seed: int, cfg: RunConfig, opts: Options) -> tuple[folders.SeedLock | None, SeedResult | None, folders.Decision | None]:
    """(lock, None, decision) when ``seed`` is to be generated; (None, result, None) when it
    is settled without work; (None, None, None) while another run holds it and we wait."""
    try:
        lock = folders.SeedLock.try_acquire(out, seed)
    except OSError as exc:
        status, message = folders.write_failure(exc, f"the lock file {folders.lock_file(out, seed)}")
        hint = "" if status == "failed" else " (a file system without flock needs a local --out)"
        return None, SeedResult(seed, status, message + hint), None
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
        blocked = folders.leftover_replaced(out, seed) if d.action == "run" and d.replace else ""
    except OSError as exc:
        lock.release()
        return None, SeedResult(seed, "conflict", f"cannot check {exc.filename or out}: {exc.strerror}; left alone"), None
    if blocked:
        lock.release()
        return None, SeedResult(seed, "conflict", blocked), None
    if d.action == "run":
        return lock, None, d
    if d.action == "skip":
        folders.drop_idle_partial(out, seed)  # debris of an earlier run, if ours and its worker is gone
    lock.release()
    return None, SeedResult(seed, "skipped" if d.action == "skip" else d.action, d.message, d.summary or {}), None


class _Progress:
    """The run's progress on screen: an overall bar, one bar of frames per running seed (on
    the first free row) and a line per result or note."""

    def __init__(self, seeds: int, frames: int):
        self.frames = frames
        self.results: list[SeedResult] = []
        self.bars: dict[int, tqdm] = {}
        self.rows: dict[int, int] = {}  # the screen row of each seed's bar (0 is the overall bar)
        self.overall = tqdm(total=seeds, desc="seeds", unit="seed", position=0, dynamic_ncols=True)

    def report(self, r: SeedResult) -> None:
        self.results.append(r)
        self.overall.update(1)
        tqdm.write(one_line(r))

    def bar(self, seed: int) -> tqdm:
        if seed not in self.bars:
            self.rows[seed] = min(p for p in range(1, len(self.bars) + 2) if p not in self.rows.values())
            self.bars[seed] = tqdm(total=self.frames, desc=f"seed {seed} frames", unit="frame",
                                   position=self.rows[seed], leave=False, dynamic_ncols=True)
        return self.bars[seed]

    def handle(self, e: dict) -> None:
        """Show one event of the executor."""
        seed, kind = e["seed"], e["event"]
        if kind == "result":
            if seed in self.bars:
                self.bars.pop(seed).close()
                self.rows.pop(seed)
            self.report(_result(e["outcome"], e["attempts"]))
        elif kind == "note":
            tqdm.write(f"seed {seed}: {e['message']}")
        elif kind == "retry":
            tqdm.write(f"seed {seed}: attempt {e['attempt'] - 1} lost ({e['cause']}); retrying: attempt "
                       f"{e['attempt']} of {e['attempts']}, its partial folder removed first")
            self.bar(seed).reset()
        elif kind == "start":
            self.bar(seed).total = e["frames"]
            self.bar(seed).refresh()
        elif kind == "frame":
            self.bar(seed).update(1)

    def close(self) -> None:
        for b in self.bars.values():
            b.close()
        self.overall.close()


def run_seeds(out: Path, seeds: list[int], cfg: RunConfig, opts: Options, executor: Executor | None = None) -> list[SeedResult]:
    """Run ``seeds`` on ``executor`` (default: the local one with ``opts.workers`` processes);
    returns their results. Each seed is locked and decided here, computed by the executor,
    and unlocked once its result is back."""
    if executor is None:
        from .executors.local import LocalExecutor

        executor = LocalExecutor(opts.workers)
    INTERRUPTED.clear()
    SIGNALS.clear()
    pending = list(seeds)
    locks: dict[int, folders.SeedLock] = {}
    announced: set[int] = set()
    progress = _Progress(len(seeds), cfg.frames * len(cfg.trajectories))
    try:
        while pending or locks:
            waiting = []
            while pending and executor.room() > 0:
                seed = pending.pop(0)
                lock, settled, decision = _claim(out, seed, cfg, opts)
                if settled:
                    progress.report(settled)
                elif lock is None:
                    waiting.append(seed)
                    if seed not in announced:
                        announced.add(seed)
                        tqdm.write(f"seed {seed}: being written by another run; waiting (--wait)")
                else:
                    if decision.message:
                        tqdm.write(f"seed {seed}: {decision.message}")
                    locks[seed] = lock
                    executor.submit(SeedJob(seed, str(Path(out).absolute()), cfg.to_dict(), decision.replace, lock.fd,
                                            executor=executor.name))
            pending = waiting + pending
            for e in executor.events(timeout=0.2):
                if e["event"] == "result":
                    locks.pop(e["seed"]).release()
                progress.handle(e)
            if INTERRUPTED.is_set():
                raise KeyboardInterrupt
    except KeyboardInterrupt:
        executor.cancel_all()  # kills what runs, removes the partial folders it made
        for lock in locks.values():
            lock.release()
        progress.close()
        raise
    progress.close()
    return progress.results


def _result(o: Outcome, attempts: int) -> SeedResult:
    message = o.message
    if o.status == "done" and attempts > 1:
        message = f"retried: complete on attempt {attempts}"
    return SeedResult(o.seed, o.status, message, o.summary, o.seconds, attempts, o.node)


def one_line(r: SeedResult) -> str:
    where = f" on node {r.node}" if r.node else ""
    if r.status == "failed":
        return f"seed {r.seed}: FAILED after {r.seconds:.0f} s{where}: {r.message}"
    if r.status != "done":
        return f"seed {r.seed}: {r.message}"
    s = r.summary
    return (f"seed {r.seed}: {s.get('frames', 0)} frames, {s.get('points', 0):,} points, "
            f"{s.get('visible_tracks', 0):,} visible tracks, {r.seconds:.0f} s{where}"
            + (f" ({r.message})" if r.message else ""))
