"""Named registries of pluggable parts, filled by scanning the package that holds them
(standard library only, and nothing of this project: every layer may import it).

A part registers itself in the file that defines it: a trajectory kind in ``trajectories/``,
an executor in ``generator/batch/executors/``, an export (a sink) in ``exporters/``. Each of
those packages owns one :class:`Registry` naming that package; the first lookup imports
every module of it (:func:`import_modules`), so a file dropped into the package is found
with no list to edit. Entries are listed in name order, whatever order the files were
imported in."""

from __future__ import annotations

import importlib
import pkgutil
import re
from typing import Generic, Iterator, TypeVar

T = TypeVar("T")
NAME = re.compile(r"[a-z][a-z0-9_]*")  # names become folder names, option values and config keys


class RegistryError(ValueError):
    """A name registered twice, a malformed name, or an unknown one (one line, listing the known names)."""


def import_modules(package: str) -> list[str]:
    """Import every module of ``package`` (its top level, in name order; names starting with
    ``_`` are skipped), so that the registrations they make at import are done. Returns the
    modules' full names."""
    pkg = importlib.import_module(package)
    names = sorted(m.name for m in pkgutil.iter_modules(pkg.__path__) if not m.name.startswith("_"))
    for name in names:
        importlib.import_module(f"{package}.{name}")
    return [f"{package}.{name}" for name in names]


def origin(thing) -> str:
    """Where ``thing`` (a function or a class) is defined: 'module.qualname'."""
    return f"{thing.__module__}.{thing.__qualname__}"


class Registry(Generic[T]):
    """``name -> entry`` for one kind of part (``what``, e.g. "trajectory kind"), filled by the
    modules of ``package``, which are imported on the first lookup."""

    def __init__(self, what: str, package: str):
        self.what, self.package = what, package
        self.entries: dict[str, T] = {}
        self.origins: dict[str, str] = {}
        self.scanned = False

    def add(self, name: str, entry: T, where: str) -> T:
        """Register ``entry`` as ``name``; ``where`` says where it is defined (:func:`origin`).
        The same name from the same place again (a module imported twice) replaces it; from
        another place it is an error."""
        if not isinstance(name, str) or not NAME.fullmatch(name):
            raise RegistryError(f"{self.what} name {name!r} (in {where}): use lowercase letters, digits and _, "
                                "starting with a letter")
        if name in self.origins and self.origins[name] != where:
            raise RegistryError(f"{self.what} {name!r} is registered twice, in {self.origins[name]} and in {where}: "
                                "rename one")
        self.entries[name], self.origins[name] = entry, where
        return entry

    def scan(self) -> None:
        """Import every module of the package (again: a module added to it since is found)."""
        self.scanned = True  # before importing: a module that looks names up while it is imported sees those so far
        import_modules(self.package)

    def names(self) -> tuple[str, ...]:
        """Every registered name, in name order."""
        if not self.scanned:
            self.scan()
        return tuple(sorted(self.entries))

    def get(self, name: str) -> T:
        """The entry called ``name``; RegistryError listing the known names if there is none."""
        known = self.names()
        if name not in self.entries:
            raise RegistryError(f"unknown {self.what} {name!r}; known: {', '.join(known)}")
        return self.entries[name]

    def items(self) -> list[tuple[str, T]]:
        """(name, entry) pairs, in name order."""
        return [(name, self.entries[name]) for name in self.names()]

    def __contains__(self, name: object) -> bool:
        return name in self.names()

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())
