"""The code's shape (issue #37): no import cycle between the project's files, and no private
name (``_x``) of one module used from another, tests included. Read from the source with
``ast``: every import counts, also one inside a function (a lazy import hides a cycle, it
does not remove it)."""

from __future__ import annotations

import ast
from pathlib import Path

from conftest import ROOT

PACKAGES = ("generator", "trajectories", "exporters", "evaluation", "datasets")
FOLDERS = PACKAGES + ("tests", "benchmarks", "tools")


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)  # tests, benchmarks and tools by their path too (tests import helpers by bare name)


def source_files() -> dict[str, Path]:
    files = {}
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            if ".venv" not in path.parts:
                files[module_name(path)] = path
    return files


FILES = source_files()
TEST_HELPERS = {p.stem: name for name, p in FILES.items() if name.startswith("tests.")}  # `import scenes`


def resolve(importer: str, path: Path, node: ast.ImportFrom) -> str:
    """The absolute module an ``ImportFrom`` names (relative imports resolved)."""
    if not node.level:
        return node.module or ""
    package = importer.split(".") if path.name == "__init__.py" else importer.split(".")[:-1]
    base = package[:len(package) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def project_module(name: str) -> str | None:
    """The project file a dotted name refers to (the longest prefix that is one), or None."""
    if name in TEST_HELPERS:
        return TEST_HELPERS[name]
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        if ".".join(parts[:k]) in FILES:
            return ".".join(parts[:k])
    return None


def imports(name: str, path: Path) -> list[tuple[str, str | None, int]]:
    """(imported project module, name imported from it or None, line) of every import in a file."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(m, None, node.lineno) for a in node.names if (m := project_module(a.name))]
        elif isinstance(node, ast.ImportFrom):
            base = resolve(name, path, node)
            for a in node.names:
                sub = project_module(f"{base}.{a.name}")
                if sub is not None and sub == f"{base}.{a.name}":  # `from package import module`
                    out.append((sub, None, node.lineno))
                elif (m := project_module(base)) is not None:
                    out.append((m, a.name, node.lineno))
    return out


GRAPH = {name: imports(name, path) for name, path in FILES.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one file (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, children = work[-1]
            w = next(children, None)
            if w is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        x = stack.pop()
                        on.discard(x)
                        comp.append(x)
                        if x == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
            elif w not in index:
                index[w] = low[w] = counter[0]
                counter[0] += 1
                stack.append(w)
                on.add(w)
                work.append((w, iter(sorted(graph.get(w, ())))))
            elif w in on:
                low[v] = min(low[v], index[w])
    return out


def test_no_import_cycle_between_files():
    edges = {name: {m for m, _, _ in found if m != name} for name, found in GRAPH.items()}
    found = cycles(edges)
    assert not found, "import cycles between files: " + "; ".join(" <-> ".join(c) for c in found)


def test_no_private_name_is_used_from_another_module():
    offences = []
    for name, found in GRAPH.items():
        for module, imported, line in found:
            if imported and imported.startswith("_") and not imported.startswith("__") and module != name:
                offences.append(f"{FILES[name].relative_to(ROOT)}:{line} imports {imported} from {module}")
        tree = ast.parse(FILES[name].read_text())
        aliases = {a.asname or a.name: a.name for node in ast.walk(tree) if isinstance(node, ast.Import)
                   for a in node.names if project_module(a.name)}
        aliases |= {a.asname or a.name: f"{resolve(name, FILES[name], node)}.{a.name}"
                    for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) for a in node.names
                    if project_module(f"{resolve(name, FILES[name], node)}.{a.name}") ==
                    f"{resolve(name, FILES[name], node)}.{a.name}"}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
                    and isinstance(node.value, ast.Name) and node.value.id in aliases):
                offences.append(f"{FILES[name].relative_to(ROOT)}:{node.lineno} uses {node.value.id}.{node.attr}")
    assert not offences, "private names used from another module:\n" + "\n".join(sorted(set(offences)))
