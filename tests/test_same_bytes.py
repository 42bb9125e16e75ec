"""The float64 geometry of the pixel ground truth gives the same bits whatever BLAS kernel
numpy's OpenBLAS picks for the CPU (docs/guarantees.md, "Same bytes"): the moving parts'
world vertices (the triangles the depth is cast into), the motion optical flow applies, and
the camera transforms of the COLMAP, COCO and box exports.
OpenBLAS picks its kernel by CPU model; ``OPENBLAS_CORETYPE`` makes it pretend to be another
one, which is how a second machine is stood in for here."""

import subprocess
import sys
from pathlib import Path

import numpy as np

from generator.geometry.camera import affine_inverse, matmul_exact

ROOT = Path(__file__).resolve().parents[1]
CORES = ("Sandybridge", "Haswell", "SkylakeX")  # no FMA; AVX2 + FMA; AVX-512

PROBE = """
import hashlib, sys
import numpy as np
from generator.geometry.camera import affine_inverse, invert_rigid, matmul_exact, turn_normals, world_to_camera
from generator.geometry.parts import MeshPart

rng = np.random.default_rng(0)
ours, numpys = hashlib.sha256(), hashlib.sha256()
for _ in range(20):
    q = rng.normal(size=4)
    w, x, y, z = q / np.sqrt((q * q).sum())  # a rotation built without BLAS or LAPACK
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m_now, m_then = np.eye(4), np.eye(4)
    m_now[:3, :3], m_now[:3, 3] = r * rng.uniform(0.2, 3, 3), rng.uniform(-300, 300, 3)
    m_then[:3, :3], m_then[:3, 3] = r.T, rng.uniform(-300, 300, 3)
    part = MeshPart("p", "p", rng.uniform(-20, 20, (3000, 3)), np.zeros((0, 3), int), dynamic=True, matrix=m_now)
    ours.update(part.world_vertices().tobytes())
    ours.update(matmul_exact(m_then, affine_inverse(m_now)).tobytes())
    pose = m_then.copy()
    pose[:3, :3] = r  # a camera: COLMAP's cam_from_world and the projections of boxes and COCO
    ours.update(invert_rigid(pose).tobytes())
    ours.update(world_to_camera(part.vertices, pose).tobytes())
    ours.update(turn_normals(m_now, part.vertices).tobytes())
    numpys.update((part.vertices @ m_now[:3, :3].T).tobytes())
    numpys.update(np.linalg.inv(m_now).tobytes())
    numpys.update(((part.vertices - m_then[:3, 3]) @ r).tobytes())
print(ours.hexdigest(), numpys.hexdigest())
"""


def _digests(core: str) -> tuple[str, str]:
    env = {"OPENBLAS_CORETYPE": core, "PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    ours, numpys = out.stdout.split()
    return ours, numpys


def test_moving_parts_and_flow_motion_do_not_depend_on_the_blas_kernel():
    digests = [_digests(core) for core in CORES]
    assert len({ours for ours, _ in digests}) == 1, "the ground truth's float64 geometry changes with the BLAS kernel"
    # the control: numpy's own @ and inv on the same inputs must differ between the kernels,
    # or the comparison above saw one kernel three times (numpy's wheel bundles OpenBLAS, which
    # honours OPENBLAS_CORETYPE on x86-64, the machine this project's commands are for)
    assert len({numpys for _, numpys in digests}) > 1, "OPENBLAS_CORETYPE changed nothing here: the test compares nothing"


def test_affine_inverse_and_products_are_float64_exact_to_round_off():
    rng = np.random.default_rng(3)
    m = np.tile(np.eye(4), (50, 1, 1))
    m[:, :3, :3] = rng.normal(size=(50, 3, 3)) + 2 * np.eye(3)  # sheared, scaled, some mirrored
    m[:, :3, 3] = rng.uniform(-500, 500, (50, 3))
    inv = affine_inverse(m)
    assert np.array_equal(inv[:, 3], np.tile([0, 0, 0, 1.0], (50, 1)))
    assert np.allclose(inv, np.linalg.inv(m), rtol=1e-12, atol=1e-12)
    assert np.abs(matmul_exact(inv, m) - np.eye(4)).max() < 1e-12
    a, b = rng.normal(size=(7, 2, 3)), rng.normal(size=(7, 3, 5))
    assert np.allclose(matmul_exact(a, b), a @ b, rtol=0, atol=1e-14)
