"""docs/architecture.md's recipes work as written (issue #37): each recipe file, dropped into
a copy of this checkout with no other edit, is found, and its commands run and write a JSON
file holding the file's base name. A copy per recipe, so no recipe sees another."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import ROOT

GUIDE = ROOT / "docs" / "architecture.md"
RECIPE = re.compile(r"```python\n# file: (?P<path>\S+)\n(?P<code>.*?)```\s*```bash\n# try:\n(?P<commands>.*?)```", re.S)


def recipes() -> list[tuple[str, str, str]]:
    """(path, file text, commands) of every recipe in the guide."""
    found = [(m["path"], f"# file: {m['path']}\n{m['code']}", m["commands"]) for m in RECIPE.finditer(GUIDE.read_text())]
    assert found, f"no recipe in {GUIDE}"
    return found


def checkout_files() -> list[str]:
    """The files of this checkout: tracked, and new ones git does not ignore (what a commit of
    the working tree would hold)."""
    r = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return [f for f in r.stdout.splitlines() if (ROOT / f).is_file()]


def clone(to: Path) -> Path:
    for rel in checkout_files():
        (to / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / rel, to / rel)
    (to / ".venv").symlink_to(ROOT / ".venv")  # the clone's own environment, as bootstrap.sh would make it
    return to


def test_the_guide_has_one_recipe_per_kind_of_part():
    names = {Path(path).parts[0] if not path.startswith("generator/") else "/".join(Path(path).parts[:-1])
             for path, _, _ in recipes()}
    assert {"exporters", "trajectories", "generator/scene/catalogue", "generator/batch/executors"} <= names, names
    assert len(recipes()) >= 5


@pytest.mark.pipeline
@pytest.mark.parametrize("path, text, commands", recipes(), ids=[Path(p).stem for p, _, _ in recipes()])
def test_a_recipe_dropped_into_a_clone_works(path, text, commands, tmp_path):
    root = clone(tmp_path / "clone")
    assert not (root / path).exists(), f"{path} is already part of the checkout"
    (root / path).write_text(text)
    env = {k: v for k, v in os.environ.items() if k not in ("OCIO", "PYTHONPATH")}
    r = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", commands], cwd=root, capture_output=True, text=True,
                       env=env, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    name = Path(path).stem
    written = [p for p in (root / "try").rglob("*.json") if name in p.read_text(errors="replace")]
    assert written, f"no JSON file under try/ names {name}"
