"""docs/format.md, "Opening the outputs in other tools": every Python snippet runs as printed,
each in its own process, from a folder whose ``output/seed_000000`` is a real tiny seed, and
gives what its text promises (a non-empty fused mesh, exact poses, masks and tracks)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SECTION = "## Opening the outputs in other tools"

# What each snippet must give, keyed by a call only that snippet makes; appended to it and run
# in the same process, so a snippet that runs but gives something else fails too.
CHECKS = {
    "o3d.t.io.read_point_cloud": (
        "assert len(xyz) == len(label) > 0 and len(mesh.triangles) > 0 and len(sfm.points) > 0"),
    "create_from_depth_image": (
        "i, j = np.nonzero(np.isfinite(f.depth)); z = f.depth[i, j].astype(np.float64)\n"
        "cam = np.stack([(j + 0.5 - f.K[0, 2]) / f.K[0, 0] * z, (i + 0.5 - f.K[1, 2]) / f.K[1, 1] * z, z], 1)\n"
        "ref = cam @ f.pose[:3, :3].T + f.pose[:3, 3]\n"
        "got = cloud.point.positions.numpy()\n"
        "from scipy.spatial import cKDTree\n"  # Open3D's parallel kernel gives the points in no fixed order
        "tol = 1e-4 * max(1.0, float(z.max()))\n"
        "assert got.shape == ref.shape and cKDTree(ref).query(got)[0].max() < tol and cKDTree(got).query(ref)[0].max() < tol"),
    "VoxelBlockGrid": "assert mesh.vertex.positions.shape[0] > 0",
    "pycolmap.Reconstruction": (
        "from datasets import Scene\n"
        "pose = Scene('output/seed_000000')['orbit'][0].pose\n"
        "assert image.name == 'rgb_000000.png' and abs(cam_from_world - np.linalg.inv(pose)[:3]).max() < 1e-9\n"
        "assert 0 <= error < 1e-9"),
    "transforms.json": (
        "from datasets import Scene\n"
        "assert abs(world_from_camera - Scene('output/seed_000000')['orbit'][0].pose).max() < 1e-9"),
    "pycocotools": (
        "from datasets import Scene\n"
        "inst = Scene('output/seed_000000')['orbit'][0].instance\n"
        "assert (mask.astype(bool) == (inst == anns[0]['instance_id'])).all() and mask.any()"),
    "OpenEXR.File": (
        "from datasets import Scene\n"
        "fr = Scene('output/seed_000000')['orbit'][0]\n"
        "lin = fr.rgb_linear.astype(np.float32)\n"
        "assert (bgr[..., ::-1] == lin).all() and (np.asarray(rgb_fi) == lin).all() and (rgb == fr.rgb_linear).all()\n"
        "assert np.array_equal(depth, fr.depth) and np.array_equal(label, fr.label)\n"
        "assert np.array_equal(flow, fr.flow, equal_nan=True)\n"
        "assert np.array_equal(ids[..., 0].view(np.int32), fr.instance)\n"
        "assert np.array_equal(ids[..., 1].view(np.int32), fr.label)"),
    "h5py.File": (
        "from datasets import Scene\n"
        "v = Scene('output/seed_000000')['orbit'].visible_tracks(t)\n"
        "assert len(ids) > 0 and np.array_equal(ids, v['ids']) and np.array_equal(xy, v['xy']) and 'pixels' in unit"),
}


def snippets() -> list[str]:
    text = (ROOT / "docs" / "format.md").read_text()
    start = text.index(SECTION)
    end = text.find("\n## ", start + len(SECTION))
    return re.findall(r"```python\n(.*?)```", text[start:end if end > 0 else None], re.S)


def check_for(code: str) -> str:
    found = [check for key, check in CHECKS.items() if key in code]
    assert len(found) == 1, f"no single check for the snippet starting {code.splitlines()[0]!r}"
    return found[0]


def test_every_snippet_has_its_check():
    codes = snippets()
    assert len(codes) == len(CHECKS)
    for code in codes:
        check_for(code)


@pytest.mark.parametrize("index", range(len(CHECKS)))
def test_the_snippet_runs_on_a_real_seed(index, seed_folder, tmp_path):
    (tmp_path / "output").mkdir()
    (tmp_path / "output" / "seed_000000").symlink_to(seed_folder)
    code = snippets()[index]
    script = tmp_path / "snippet.py"
    script.write_text(code + "\nimport numpy as np\n" + check_for(code) + "\n")
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, code + "\n" + r.stdout[-2000:] + r.stderr[-3000:]
