"""Test configuration: real Blender (bpy) scenes built in code, saved to temporary files."""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
os.environ.setdefault("BUILDEE_BLENDER_LOG", str(Path(os.environ.get("TMPDIR", "/tmp")) / f"buildee-tests-{os.getpid()}.log"))
