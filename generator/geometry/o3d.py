"""Import open3d safely next to bpy.

bpy and open3d both ship libtbb; if open3d's copy is loaded first, ``import bpy`` later
fails with an undefined TBB symbol. Loading bpy's own libtbb (without importing bpy) before
open3d makes both work in one process, in either import order.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
import sys


bpy_tbb_loaded = False  # True once bpy's libtbb is loaded: bpy can then be imported after open3d


def _preload_bpy_tbb() -> None:
    global bpy_tbb_loaded
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        return
    libdir = os.path.join(os.path.dirname(spec.origin), "lib")
    if not os.path.isdir(libdir):
        return
    for name in sorted(os.listdir(libdir)):
        if name.startswith("libtbb") and ".so" in name:
            ctypes.CDLL(os.path.join(libdir, name), mode=ctypes.RTLD_GLOBAL)
            bpy_tbb_loaded = True


def import_open3d():
    """Return the open3d module, loaded so that bpy can still be imported afterwards."""
    if "open3d" not in sys.modules and "bpy" not in sys.modules:
        _preload_bpy_tbb()
    import open3d

    return open3d
