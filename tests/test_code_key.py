"""The key of cached sites (generator/envs/scenes.py): it reads every source file that a
site build runs, found from the import statements (generator/envs/code_key.py)."""

import subprocess
import sys

import pytest

from generator.envs.scenes import site_code_key


def test_site_code_key_follows_the_site_generator_sources(tmp_path):
    import shutil

    from generator.envs.scenes import PACKAGE_ROOT

    copy = tmp_path / "generator"
    shutil.copytree(PACKAGE_ROOT, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert site_code_key(copy) == site_code_key()
    (copy / "scene" / "README.txt").write_text("not code")
    assert site_code_key(copy) == site_code_key()
    # the site's own modules and helpers they reach only through other modules (the
    # hand-kept list of sources used to miss the last three)
    for rel in ("scene/site.py", "geometry/portable_math.py", "geometry/exact_kernels.py",
                "geometry/nearest_rotation.py"):
        f = copy / rel
        text = f.read_text()
        f.write_text(text + "\n")
        assert site_code_key(copy) != site_code_key(), rel
        f.write_text(text)
    assert site_code_key(copy) == site_code_key()
    # code the site build never imports does not count
    f = copy / "batch" / "verify.py"
    f.write_text(f.read_text() + "\n")
    assert site_code_key(copy) == site_code_key()
    (copy / "scene" / "site.py").unlink()
    with pytest.raises(FileNotFoundError, match="site_code_key"):
        site_code_key(tmp_path / "nowhere")


def test_site_code_key_covers_every_module_a_site_build_loads(tmp_path):
    """Every module of the package loaded while a site is built (in a fresh process) is
    among the files the key reads: an import the key's reader cannot see would let a
    change to it reuse a stale cached site."""
    from generator.envs.code_key import import_closure
    from generator.envs.scenes import PACKAGE_ROOT, SITE_ENTRIES

    script = (
        "import sys, pathlib\n"
        "from generator.envs.scenes import site_scene\n"
        f"site_scene(4, 'small', {str(tmp_path)!r})\n"
        "root = pathlib.Path(sys.modules['generator'].__file__).parent\n"
        "for m in list(sys.modules.values()):\n"
        "    f = getattr(m, '__file__', None)\n"
        "    if f and pathlib.Path(f).is_relative_to(root): print(pathlib.Path(f).relative_to(root).as_posix())\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    loaded = {line for line in out.splitlines() if line.endswith(".py")}
    covered = {f.relative_to(PACKAGE_ROOT).as_posix() for f in import_closure(PACKAGE_ROOT, SITE_ENTRIES)}
    assert "scene/site.py" in loaded and "geometry/portable_math.py" in loaded
    assert loaded <= covered, sorted(loaded - covered)


def test_import_closure_reads_every_kind_of_import(tmp_path):
    from generator.envs.code_key import import_closure

    pkg = tmp_path / "generator"
    files = {
        "__init__.py": "",
        "a/__init__.py": "",
        "a/entry.py": "from .b import f\nfrom ..c import d\nimport generator.e\n"
                      "def later():\n    from . import g\n    from generator.h.i import x\n",
        "a/b.py": "import numpy\nfrom . import c_sibling\n",
        "a/c_sibling.py": "",
        "a/g.py": "",
        "c/__init__.py": "",
        "c/d.py": "from ..a import b\n",
        "e.py": "",
        "h/__init__.py": "", "h/i.py": "",
        "unused.py": "",
    }
    for rel, text in files.items():
        (pkg / rel).parent.mkdir(parents=True, exist_ok=True)
        (pkg / rel).write_text(text)
    got = {f.relative_to(pkg).as_posix() for f in import_closure(pkg, ("a/entry.py",))}
    assert got == set(files) - {"unused.py"}
    with pytest.raises(FileNotFoundError, match="missing"):
        import_closure(pkg, ("nowhere.py",))
