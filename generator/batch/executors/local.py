"""The local executor: up to ``workers`` seeds at once on this machine, each in its own
worker process driven by a thread of the runner (seed.produce_seed). The worker shares the
seed's lock descriptor and dies with the runner (PR_SET_PDEATHSIG). A worker that dies is
a failed seed (no retry). bpy-free."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import threading
from dataclasses import replace
from pathlib import Path

from generator.cli_args import Option, int_at_least

from .. import folders
from . import Executor, SeedJob, produce_seed, register_executor
from .seed import CANCEL_WAIT


@register_executor("local", "worker processes on this machine", options=(
    Option("--workers", "local executor: seeds processed at once, one process each (default: 1; Cycles already "
                        "uses every core)", type=int_at_least(1, "workers")),))
class LocalExecutor(Executor):
    def __init__(self, workers: int = 1):
        self.workers = workers
        self.queue: queue.Queue = queue.Queue()
        self.running: dict[int, tuple[SeedJob, threading.Thread]] = {}
        self.procs: dict[int, subprocess.Popen] = {}
        self.made: set[int] = set()  # seeds whose partial folder this run made (their worker started)
        self.cancelled = threading.Event()

    @classmethod
    def from_options(cls, out: Path, options) -> "LocalExecutor":
        return cls(options.workers or 1)

    def room(self) -> int:
        return self.workers - len(self.running)

    def submit(self, job: SeedJob) -> None:
        env = job.env | {k: v for k, v in os.environ.items() if k.startswith(self.FORWARDED_ENV_PREFIX)}
        job = replace(job, env=env)
        thread = threading.Thread(target=self._run, args=(job,), daemon=True)
        self.running[job.seed] = (job, thread)
        thread.start()

    def _run(self, job: SeedJob) -> None:
        def emit(event: dict) -> None:
            self.queue.put({"seed": job.seed, **event})

        def started(proc: subprocess.Popen) -> None:
            self.made.add(job.seed)
            self.procs[job.seed] = proc
            if self.cancelled.is_set():  # cancel_all ran while this one was starting
                _kill(proc)

        try:
            outcome = produce_seed(job, emit, started, self.cancelled)
        except Exception as exc:  # reported as the seed's failure, never lost
            from . import Outcome

            outcome = Outcome(job.seed, "failed", f"{exc.__class__.__name__}: {exc}")
        self.queue.put({"seed": job.seed, "event": "result", "outcome": outcome, "attempts": 1})

    def events(self, timeout: float) -> list[dict]:
        got = []
        try:
            got.append(self.queue.get(timeout=timeout))
            while True:
                got.append(self.queue.get_nowait())
        except queue.Empty:
            pass
        for e in got:
            if e["event"] == "result":
                self.running.pop(e["seed"], (None, None))[1].join()
                self.procs.pop(e["seed"], None)
        return got

    def cancel_all(self) -> None:
        """Kill every worker process, stop every wait for a work lock, wait for each thread,
        then remove the partial folders this run made (ours: marked, and no worker left)."""
        self.cancelled.set()
        for proc in list(self.procs.values()):
            _kill(proc)
        for seed, (job, thread) in list(self.running.items()):
            thread.join()
            if seed in self.made:
                folders.drop_idle_partial(Path(job.out), seed, wait=CANCEL_WAIT)
        self.running.clear()
        self.procs.clear()


def _kill(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGTERM)
    except ProcessLookupError:
        pass
