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

Each executor registers itself in its own module of this package with
:func:`register_executor`: its name (``--executor``), a phrase for ``--help``, the
command-line options it adds (generator.cli_args.Option), a check of them, and its factory
(the class's ``from_options``). Every module here is imported on the first lookup, so a new
executor is one new file. Today: ``local`` (worker processes on this machine, the default)
and ``ray`` (Ray tasks on a cluster). bpy-free."""

from __future__ import annotations

import argparse
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from generator.cli_args import Option
from generator.registry import Registry, RegistryError, origin

from .seed import Outcome, SeedJob, produce_seed

__all__ = ["DEFAULT_EXECUTOR", "EXECUTORS", "Executor", "ExecutorEntry", "ExecutorError", "Outcome", "SeedJob",
           "add_executor_arguments", "executor_arguments_problem", "make_executor", "produce_seed",
           "register_executor"]

DEFAULT_EXECUTOR = "local"


class ExecutorError(RuntimeError):
    """An executor that cannot start (the message is one line saying what to do)."""


class Executor(ABC):
    name = ""  # set by register_executor
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

    @classmethod
    def from_options(cls, out: Path, options: argparse.Namespace) -> "Executor":
        """The executor for a run into ``out``, from the parsed command line ``options`` (its own
        options are None where not given)."""
        return cls()

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


@dataclass(frozen=True)
class ExecutorEntry:
    """A registered executor: ``name`` (``--executor NAME``), ``help`` (what it is, a phrase
    for ``--help``), ``factory(out, options)``, its command-line ``options`` (given as None
    when left out, so that one given with another executor is refused) and ``check(options)``:
    a one-line problem with them when this executor is chosen, or None."""

    name: str
    help: str
    factory: Callable[[Path, argparse.Namespace], Executor]
    options: tuple[Option, ...] = ()
    check: Callable[[argparse.Namespace], str | None] | None = None


EXECUTORS: Registry[ExecutorEntry] = Registry("executor", __name__)


def register_executor(name: str, help: str, options: tuple[Option, ...] = (),
                      check: Callable[[argparse.Namespace], str | None] | None = None):
    """Class decorator on an :class:`Executor` subclass: ``@register_executor("ray", "one Ray
    task per seed", options=(Option("--ray-address", ...),))``."""

    def wrap(cls):
        cls.name = name
        EXECUTORS.add(name, ExecutorEntry(name, help, cls.from_options, tuple(options), check), origin(cls))
        return cls

    return wrap


def add_executor_arguments(parser: argparse.ArgumentParser) -> None:
    """``--executor`` (choices: the registered executors) and every executor's own options."""
    entries = [entry for _, entry in EXECUTORS.items()]
    said = [f"{e.name} ({e.help}{'; default' if e.name == DEFAULT_EXECUTOR else ''})" for e in entries]
    parser.add_argument("--executor", choices=[e.name for e in entries], default=DEFAULT_EXECUTOR,
                        help="where the seeds run: " + (", ".join(said[:-1]) + " or " if len(said) > 1 else "")
                             + said[-1])
    for entry in entries:
        for option in entry.options:
            option.add_to(parser)


def executor_arguments_problem(args: argparse.Namespace) -> str | None:
    """One line saying what is wrong with the executor options of the parsed ``args`` (the
    chosen executor's check first, then any other executor's option given), or None."""
    chosen = EXECUTORS.get(args.executor)
    problem = chosen.check(args) if chosen.check is not None else None
    if problem:
        return problem
    for name, entry in EXECUTORS.items():
        given = [o.flag for o in entry.options if name != args.executor and getattr(args, o.dest) is not None]
        if given:
            return f"{given[0]} applies to --executor {name}"
    return None


def make_executor(name: str, out, options: argparse.Namespace) -> Executor:
    """The executor called ``name`` for a run into ``out``, from the parsed command line
    ``options``; ExecutorError (one line) if there is none of that name or it cannot start."""
    try:
        entry = EXECUTORS.get(name)
    except RegistryError as exc:
        raise ExecutorError(str(exc)) from None
    return entry.factory(Path(out), options)
