"""Which source files some code runs: the import closure of a few modules of the package,
found by reading their ``import`` statements (no import is executed).

Used to key cached builds by the code that made them (:func:`generator.envs.scenes.site_code_key`):
listing the sources by hand misses a helper module the day someone imports a new one.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = "generator"  # absolute imports of this name resolve under the package root


def import_closure(root: Path, entries: tuple[str, ...]) -> list[Path]:
    """Sorted ``.py`` files under ``root`` (the package folder) that the ``entries`` (paths
    relative to ``root``) import, directly or through each other, with every imported
    package's ``__init__.py`` and every module of a package that sets ``SCANNED = True``
    (loaded by name at run time); imports anywhere in a file count (inside functions too).
    A missing entry is a FileNotFoundError."""
    root = Path(root)
    todo = []
    for rel in entries:
        path = root / rel
        if not path.is_file():
            raise FileNotFoundError(f"import_closure: {path} is missing")
        todo.append(path)
    seen: set[Path] = set()
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        todo.extend(_imported_files(root, path))
        todo.extend(_scanned_modules(path))
    return sorted(seen)


def _scanned_modules(path: Path) -> list[Path]:
    """Every module of the package whose ``__init__.py`` is ``path``, if it sets
    ``SCANNED = True``: its modules are imported by name at run time (pkgutil, e.g. the asset
    catalogue), which no import statement shows."""
    if path.name != "__init__.py":
        return []
    for node in ast.parse(path.read_bytes(), filename=str(path)).body:
        if (isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "SCANNED" for t in node.targets)
                and isinstance(node.value, ast.Constant) and node.value.value is True):
            return sorted(path.parent.glob("*.py"))
    return []


def _imported_files(root: Path, path: Path) -> list[Path]:
    """The files under ``root`` that ``path``'s import statements name."""
    package = path.parent.relative_to(root).parts  # the package this module belongs to
    out: list[Path] = []
    for node in ast.walk(ast.parse(path.read_bytes(), filename=str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                out += _module_files(root, _absolute(alias.name.split(".")))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1] if node.level <= len(package) + 1 else None
                if base is None:
                    continue
                parts = base + tuple(node.module.split(".") if node.module else ())
            else:
                parts = _absolute(node.module.split("."))
            if parts is None:
                continue
            out += _module_files(root, parts)
            for alias in node.names:  # `from .pkg import module` names modules too
                out += _module_files(root, parts + (alias.name,), only_modules=True)
    return out


def _absolute(names: list[str]) -> tuple[str, ...] | None:
    """The parts of an absolute module name below the package, or None outside it."""
    return tuple(names[1:]) if names and names[0] == PACKAGE else None


def _module_files(root: Path, parts: tuple[str, ...] | None, only_modules: bool = False) -> list[Path]:
    """The files a module name loads: each package ``__init__.py`` on the way and the module's
    own file; ``only_modules``: nothing unless the last name is a module or a package."""
    if parts is None:
        return []
    target = root.joinpath(*parts)
    own = [p for p in (target.with_suffix(".py"), target / "__init__.py") if p.is_file()] if parts else []
    if only_modules and not own:
        return []
    inits = [root.joinpath(*parts[:k], "__init__.py") for k in range(len(parts))]
    return [p for p in inits if p.is_file()] + own
