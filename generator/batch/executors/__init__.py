"""Executors: where the seeds of a batch run are computed. The runner (runner.py) decides
what to do with each seed and holds its lock; an executor runs the seed's work
(seed.produce_seed, the same function everywhere) and reports back:

    submit(job)        start (or queue) one seed
    room()             how many more seeds it takes now
    events(timeout)    what happened since the last call: dicts with "seed" and "event":
                       "note" (message), "start" (frames), "frame", "retry" (attempt,
                       attempts, cause) and, last for each seed, "result" (outcome, attempts)
    cancel_all()       stop every seed in flight and remove the partial folders they made
    close()            give the executor's resources back

Two of them, by name (``--executor``): ``local`` (worker processes on this machine,
the default) and ``ray`` (Ray tasks on a cluster). bpy-free."""

from __future__ import annotations

from abc import ABC, abstractmethod

from .seed import Outcome, SeedJob, produce_seed

__all__ = ["DEFAULT_CPUS_PER_SEED", "DEFAULT_RETRIES", "EXECUTORS", "MIN_CPUS_PER_SEED", "Executor", "ExecutorError",
           "Outcome", "SeedJob", "produce_seed"]

EXECUTORS = ("local", "ray")
DEFAULT_CPUS_PER_SEED = 2.0  # ray: one seed per 2 CPUs (the machine measured in docs/benchmarks.md: ~2.4 GB a seed)
MIN_CPUS_PER_SEED = 0.0001  # ray: the finest fraction of a resource Ray accepts (smaller ones raise)
DEFAULT_RETRIES = 2  # ray: a seed whose worker or node dies is run at most 3 times in all


class ExecutorError(RuntimeError):
    """An executor that cannot start (the message is one line saying what to do)."""


class Executor(ABC):
    name = ""
    #: the driver forwards its environment variables with this prefix to every worker
    FORWARDED_ENV_PREFIX = "BUILDEE_"

    @abstractmethod
    def room(self) -> int: ...

    @abstractmethod
    def submit(self, job: SeedJob) -> None: ...

    @abstractmethod
    def events(self, timeout: float) -> list[dict]: ...

    @abstractmethod
    def cancel_all(self) -> None: ...

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def make_executor(name: str, out, *, workers: int = 1, address: str | None = None,
                  cpus_per_seed: float = DEFAULT_CPUS_PER_SEED, retries: int = DEFAULT_RETRIES) -> Executor:
    """The executor called ``name``; ExecutorError (one line) if it cannot start."""
    if name == "local":
        from .local import LocalExecutor

        return LocalExecutor(workers)
    if name == "ray":
        from .ray_cluster import RayExecutor

        return RayExecutor(out, address=address, cpus_per_seed=cpus_per_seed, retries=retries)
    raise ExecutorError(f"unknown executor {name!r}; choose one of {', '.join(EXECUTORS)}")
