"""The Ray executor: each seed is one Ray task (``--cpus-per-seed`` CPUs) that runs the
seed's work (seed.produce_seed: one fresh worker process per attempt, partial folder,
commit) on whichever node Ray picks. ``--out`` must be a folder every node sees at the same
path; every node present at start is checked (it sees a file the driver wrote there and can
write one of its own) before any seed is submitted.

Progress: each task sends its events to one small actor (``Progress``); the driver drains
it, so the runner's bars and lines are fed by the tasks themselves, never by watching files.

Faults: a worker process killed by a signal (the task raises ``WorkerLost``), a Ray worker
process that dies, or a node that dies makes Ray run the task again, at most ``retries``
more times; every attempt starts by removing the partial folder of the one before
(folders.start_partial). Only a committed folder is ever complete.

The driver keeps the seed's lock (runner.py) for the whole life of the task. bpy-free.
Ray (a second to import) is imported inside the functions that use it: listing the
executors (every run, ``--help``) imports this module, not Ray."""

from __future__ import annotations

import contextlib
import logging
import os
import socket
import sys
import tempfile
import threading
import time
import uuid
from dataclasses import replace
from pathlib import Path

from generator.cli_args import Option, int_at_least, positive_float

from .. import folders
from . import Executor, ExecutorError, Outcome, SeedJob, produce_seed, register_executor
from .seed import CANCEL_WAIT

DEFAULT_CPUS_PER_SEED = 2.0  # one seed per 2 CPUs (the main job in docs/benchmarks.md: 2.63 GB peak a seed)
MIN_CPUS_PER_SEED = 0.0001  # the finest fraction of a resource Ray accepts (smaller ones raise)
DEFAULT_RETRIES = 2  # a seed whose worker or node dies is run at most 3 times in all

CONNECT_TIMEOUT_S = 5.0  # TCP connection to the cluster's address
INIT_TIMEOUT_S = 60.0  # ray.init against an address that accepts connections but does not answer
PROBE_TIMEOUT_S = 120.0  # a node's check of --out (starting a Ray worker process on a busy node)
MIN_IN_FLIGHT = 32  # seeds kept submitted at once at least (queued demand lets an autoscaler grow)


class WorkerLost(RuntimeError):
    """The seed's worker process was killed by a signal: Ray runs the task again."""


class Progress:
    """The tasks' events, kept until the driver drains them (a Ray actor, one per run)."""

    def __init__(self):
        self.queue: list[dict] = []
        self.attempts: dict[int, int] = {}
        self.causes: dict[int, str] = {}

    def begin(self, seed: int) -> int:
        """A task starts working on ``seed``: returns its attempt number (1, 2, ...)."""
        n = self.attempts[seed] = self.attempts.get(seed, 0) + 1
        self.queue.append({"seed": seed, "event": "attempt", "attempt": n, "cause": self.causes.pop(seed, "")})
        return n

    def push(self, seed: int, event: dict) -> None:
        self.queue.append({"seed": seed, **event})

    def lost(self, seed: int, cause: str) -> None:
        """The attempt at ``seed`` ends in WorkerLost because of ``cause``."""
        self.causes[seed] = cause

    def flush(self) -> None:
        """Answered once every earlier call of the caller is handled (actor calls are ordered)."""

    def drain(self) -> list[dict]:
        got, self.queue = self.queue, []
        return got


def seed_task(job: SeedJob, progress, retries: int) -> Outcome:
    """One attempt at a seed, inside a Ray task."""
    import ray

    attempt = ray.get(progress.begin.remote(job.seed))

    def emit(event: dict) -> None:
        if attempt == 1 or event["event"] != "note":  # a retry's cleanup is announced by the driver
            progress.push.remote(job.seed, event)

    if not Path(job.out).is_dir():
        outcome = Outcome(job.seed, "failed", f"--out {job.out} is not visible on node {ray.util.get_node_ip_address()}: "
                                              "it must be a shared file system mounted at the same path on every node")
    else:
        outcome = produce_seed(job, emit)
    if outcome.lost and attempt <= retries:
        ray.get(progress.lost.remote(job.seed, outcome.message))
        raise WorkerLost(outcome.message)
    if outcome.lost and attempt > 1:
        outcome.message += f" (attempt {attempt} of {retries + 1})"
    outcome.node = ray.util.get_node_ip_address()
    ray.get(progress.flush.remote())  # every event of this attempt reaches the driver before the result
    return outcome


def probe_out(token: str, secret: str) -> str:
    """On one node: '' if it sees the driver's file ``token`` (with ``secret``) and can write
    beside it and import the worker; else what is wrong."""
    import importlib.util

    path = Path(token)
    try:
        if path.read_text() != secret:
            return f"sees another file at {path} (not the same file system as the driver's)"
    except FileNotFoundError:
        return f"does not see the file the driver wrote in {path.parent} (not a shared file system?)"
    except OSError as exc:
        return f"cannot read {path}: {exc.strerror}"
    mine = path.with_name(f"{path.name}.{socket.gethostname()}.{os.getpid()}")
    try:
        mine.write_text("")
        mine.unlink()
    except OSError as exc:
        return f"cannot write in {path.parent}: {exc.strerror}"
    if importlib.util.find_spec("generator.batch.worker") is None:
        return "cannot import generator.batch.worker: install this project on every node"
    return ""


OPTIONS = (
    Option("--ray-address", "ray: the cluster's HOST:PORT as `ray start --head` prints it, or auto (default: "
                            "$RAY_ADDRESS if set, else a local Ray started for this run)"),
    Option("--cpus-per-seed", f"ray: CPUs each seed reserves, at least {MIN_CPUS_PER_SEED:g}; a node runs (its "
                              f"CPUs / N) seeds at once (default: {DEFAULT_CPUS_PER_SEED:g})",
           type=positive_float(f"a positive number of CPUs, at least {MIN_CPUS_PER_SEED:g} (the finest fraction Ray "
                               "reserves)", at_least=MIN_CPUS_PER_SEED)),
    Option("--retries", f"ray: how many times a seed is run again when its worker process or its node dies "
                        f"(default: {DEFAULT_RETRIES})", type=int_at_least(0, "retries", 100)),
)


def check_options(options) -> str | None:
    """The local executor's --workers has no meaning here (say what does instead)."""
    if getattr(options, "workers", None) is not None:
        return ("--workers applies to the local executor; with --executor ray each node runs as many seeds as its "
                "CPUs allow (--cpus-per-seed)")
    return None


@register_executor("ray", "one Ray task per seed on a Ray cluster; --out must be a folder every node sees; "
                          "docs/scale.md", options=OPTIONS, check=check_options)
class RayExecutor(Executor):
    def __init__(self, out, *, address: str | None, cpus_per_seed: float = DEFAULT_CPUS_PER_SEED,
                 retries: int = DEFAULT_RETRIES):
        import ray

        self.out = Path(out).resolve()
        self.cpus_per_seed, self.retries = cpus_per_seed, retries
        self.address = _connect(address)
        try:
            self.progress = ray.remote(Progress).options(num_cpus=0).remote()
            _check_nodes(self.out, cpus_per_seed, can_grow=self.address != "local")
        except BaseException:
            ray.shutdown()
            raise
        self.task = ray.remote(seed_task).options(num_cpus=cpus_per_seed, max_retries=retries,
                                                  retry_exceptions=[WorkerLost])
        self.refs: dict = {}  # ObjectRef -> SeedJob
        self.attempts: dict[int, int] = {}
        self._slots, self._slots_at = 0, -1e9

    @classmethod
    def from_options(cls, out: Path, options) -> "RayExecutor":
        return cls(out, address=options.ray_address, cpus_per_seed=options.cpus_per_seed or DEFAULT_CPUS_PER_SEED,
                   retries=DEFAULT_RETRIES if options.retries is None else options.retries)

    def room(self) -> int:
        import ray

        if time.monotonic() - self._slots_at > 5.0:
            self._slots = sum(int(n["Resources"].get("CPU", 0) // self.cpus_per_seed) for n in ray.nodes() if n["Alive"])
            self._slots_at = time.monotonic()
        return max(MIN_IN_FLIGHT, 2 * self._slots) - len(self.refs)

    def submit(self, job: SeedJob) -> None:
        env = job.env | {k: v for k, v in os.environ.items() if k.startswith(self.FORWARDED_ENV_PREFIX)}
        job = replace(job, out=str(self.out), lock_fd=None, env=env)
        self.refs[self.task.remote(job, self.progress, self.retries)] = job

    def events(self, timeout: float) -> list[dict]:
        import ray

        refs = list(self.refs)
        if refs:
            ready, _ = ray.wait(refs, num_returns=len(refs), timeout=timeout)
        else:
            ready = []
            time.sleep(timeout)
        got = []
        for e in ray.get(self.progress.drain.remote()):
            if e["event"] != "attempt":
                got.append(e)
                continue
            self.attempts[e["seed"]] = e["attempt"]
            if e["attempt"] > 1:
                got.append({"seed": e["seed"], "event": "retry", "attempt": e["attempt"], "attempts": self.retries + 1,
                            "cause": e["cause"] or "its Ray worker process or node died"})
        for ref in ready:
            job = self.refs.pop(ref)
            try:
                outcome = ray.get(ref)
            except ray.exceptions.RayError as exc:
                outcome = Outcome(job.seed, "failed", _failure(exc, self.attempts.get(job.seed, 1)))
            got.append({"seed": job.seed, "event": "result", "outcome": outcome,
                        "attempts": self.attempts.get(job.seed, 1)})
        return got

    def cancel_all(self) -> None:
        """Cancel every task (its Ray worker is killed, and the seed's worker process with it),
        wait for them to end, then remove the partial folders they made."""
        import ray

        for ref in self.refs:
            try:
                ray.cancel(ref, force=True)
            except Exception:  # already finished
                pass
        deadline = time.monotonic() + 30.0
        for ref in self.refs:
            try:
                ray.get(ref, timeout=max(0.1, deadline - time.monotonic()))
            except Exception:
                pass
        for job in self.refs.values():
            folders.drop_idle_partial(Path(job.out), job.seed, wait=CANCEL_WAIT)  # its worker dies with its task
        self.refs.clear()

    def close(self) -> None:
        import ray

        ray.shutdown()


def _failure(exc: Exception, attempts: int) -> str:
    """One line for a task that Ray gave up on."""
    import ray

    first = (str(exc).strip().splitlines() or [exc.__class__.__name__])[0]
    if isinstance(exc, (ray.exceptions.WorkerCrashedError, ray.exceptions.NodeDiedError,
                        ray.exceptions.OutOfMemoryError)):
        return f"its Ray worker process or node died on each of {attempts} attempt(s) ({exc.__class__.__name__})"
    if isinstance(exc, ray.exceptions.TaskCancelledError):
        return "cancelled"
    return f"{exc.__class__.__name__}: {first}"


def _connect(address: str | None) -> str:
    """Join the cluster at ``address`` (else RAY_ADDRESS, else start a local Ray); returns
    the address joined ('local' for a Ray started here). ExecutorError (one line) if no
    cluster answers."""
    import ray

    source = "--ray-address" if address else "$RAY_ADDRESS"  # which one the user should mend
    address = address or os.environ.get("RAY_ADDRESS") or None
    if address and address.startswith("ray://"):
        raise ExecutorError(f"{source} {address}: Ray Client addresses (ray://) are not supported; run the "
                            "command on a node of the cluster and give the head's HOST:PORT, or auto")
    if address not in (None, "auto", "local"):
        host, _, port = address.rpartition(":")
        if not host or not port.isdigit():
            raise ExecutorError(f"{source} must be HOST:PORT (the head node's address, as `ray start --head` "
                                f"prints it) or auto; got {address!r}")
        try:
            socket.create_connection((host.strip("[]"), int(port)), timeout=CONNECT_TIMEOUT_S).close()
        except OSError as exc:
            raise ExecutorError(f"no Ray cluster answers at {address} ({exc.strerror or exc}): start one with "
                                "`ray start --head`, or leave out --ray-address (and RAY_ADDRESS) to start a local Ray")
    os.environ.setdefault("RAY_BACKEND_LOG_LEVEL", "error")  # Ray's C++ warnings would fill the terminal
    kwargs: dict = {"logging_level": logging.ERROR, "log_to_driver": False}
    if address in (None, "local"):
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # a Ray of our own reports nowhere
        kwargs["include_dashboard"] = False
    where = "the Ray started for this run" if address in (None, "local") else f"the Ray cluster at {address}"
    try:
        with _stderr_caught() as caught:
            watchdog = threading.Timer(INIT_TIMEOUT_S, _give_up, args=(where, caught))
            watchdog.daemon = True
            watchdog.start()
            try:
                ray.init(address=address or "local", **kwargs)
            finally:
                watchdog.cancel()
    except (ConnectionError, RuntimeError, ValueError) as exc:
        first = (str(exc).strip().splitlines() or [exc.__class__.__name__])[0]
        raise ExecutorError(f"cannot join {where}: {first}") from None
    return address or "local"


START_NOISE = "Set ray log level from environment variable"  # Ray's C++ core, at info level, before it applies it


class _Caught:
    """What a process wrote to file descriptor 2 while it was caught, and the real stderr."""

    def __init__(self, file, terminal: int):
        self.file, self.terminal = file, terminal

    def replay(self, fd: int) -> None:
        """The caught lines, but for Ray's log-level info line, written to ``fd``."""
        self.file.seek(0)
        kept = [line for line in self.file.read().decode(errors="replace").splitlines(True) if START_NOISE not in line]
        if kept:
            os.write(fd, "".join(kept).encode())


@contextlib.contextmanager
def _stderr_caught():
    """File descriptor 2 into a temporary file while Ray starts, then replayed to the real
    stderr without Ray's info line about RAY_BACKEND_LOG_LEVEL (printed before the level
    applies). Yields the :class:`_Caught` (the watchdog replays it before it exits)."""
    sys.stderr.flush()
    terminal = os.dup(2)
    with tempfile.TemporaryFile() as file:
        os.dup2(file.fileno(), 2)
        caught = _Caught(file, terminal)
        try:
            yield caught
        finally:
            sys.stderr.flush()
            os.dup2(terminal, 2)
            os.close(terminal)
            caught.replay(2)


def _give_up(where: str, caught: _Caught) -> None:
    caught.replay(caught.terminal)  # what Ray said while it hung is often the diagnosis
    os.write(caught.terminal, (f"error: {where} did not answer within {INIT_TIMEOUT_S:.0f} s; check the address "
                               "(`ray status` on the head node), and if the cluster uses token authentication, set "
                               "RAY_AUTH_MODE=token (docs/scale.md)\n").encode())
    os._exit(2)


def _check_nodes(out: Path, cpus_per_seed: float, can_grow: bool = True) -> None:
    """Every live node sees ``out`` (a file written here) and can write there; ExecutorError
    naming the first node that cannot. When no node has ``cpus_per_seed`` CPUs: a warning on
    a cluster that nodes can join, an ExecutorError on the Ray started for this run (the
    seeds would wait forever)."""
    import ray
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    secret = uuid.uuid4().hex
    token = out / f".ray-probe-{os.getpid()}-{secret[:8]}"
    token.write_text(secret)
    try:
        nodes = [n for n in ray.nodes() if n["Alive"]]
        probe = ray.remote(probe_out)
        refs = [probe.options(num_cpus=0, scheduling_strategy=NodeAffinitySchedulingStrategy(n["NodeID"], soft=False))
                .remote(str(token), secret) for n in nodes]
        ready, _ = ray.wait(refs, num_returns=len(refs), timeout=PROBE_TIMEOUT_S)
        for node, ref in zip(nodes, refs):
            problem = ray.get(ref) if ref in ready else f"did not answer within {PROBE_TIMEOUT_S:.0f} s"
            if problem:
                raise ExecutorError(f"node {node['NodeManagerAddress']} {problem}; --out must be a folder every "
                                    "node sees at the same path (a shared file system) and can write")
    finally:
        token.unlink(missing_ok=True)
    largest = max((n["Resources"].get("CPU", 0) for n in nodes), default=0)
    if largest < cpus_per_seed and not can_grow:
        raise ExecutorError(f"--cpus-per-seed {cpus_per_seed:g}: this machine has {largest:g} CPUs and no other "
                            f"node can join the Ray started for this run; give at most {largest:g}")
    if largest < cpus_per_seed:
        print(f"warning: no node of the cluster has {cpus_per_seed:g} CPUs now (largest: {largest:g}); the seeds wait "
              "until one joins (lower --cpus-per-seed to use these nodes)", file=sys.stderr, flush=True)
