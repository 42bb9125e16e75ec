"""bpy and open3d both ship libtbb: the order in which a process imports them matters.

Each case runs in a fresh interpreter (the order is a property of the whole process)."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=240)


def test_open3d_through_import_open3d_then_bpy_works():
    # what `evaluation` does (it never imports bpy), followed by a user's own Simulator
    r = run("from generator.geometry.o3d import import_open3d\n"
            "o3d = import_open3d()\n"
            "import evaluation.coverage\n"
            "from generator import Simulator\n"
            "import bpy\n"
            "scene = o3d.t.geometry.RaycastingScene()\n"
            "print('ok', bpy.app.version_string, type(scene).__name__)")
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.startswith("ok ")


@pytest.mark.parametrize("first", ["import generator.blender.session", "from generator import Simulator; Simulator"])
def test_raw_open3d_before_bpy_is_refused_with_the_remedy(first):
    r = run(f"import open3d\n{first}")
    assert r.returncode != 0
    assert "open3d was imported before bpy" in r.stderr and "import_open3d()" in r.stderr
