"""The float64 geometry of a seed gives the same bits whatever kernels the CPU makes numpy,
OpenBLAS and the C library pick (docs/guarantees.md, "Same bytes"): the moving parts' world
vertices (the triangles the depth is cast into), the motion optical flow applies, the camera
transforms of the COLMAP, COCO and box exports, the site's plan, the trajectories' poses and
the 3D boxes.
Each library picks its kernels by CPU model; environment variables make it pretend to be
another one, which is how a second machine is stood in for here: ``OPENBLAS_CORETYPE``
(OpenBLAS), ``NPY_DISABLE_CPU_FEATURES`` (numpy's SIMD loops, e.g. its AVX-512 ``arctan2``
and ``power``) and ``GLIBC_TUNABLES`` (the C library's FMA variants of ``sin``, ``cos``,
``atan2``)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import cpu_flags

from generator.geometry.boxes import Box3D
from generator.geometry.camera import affine_inverse, matmul_exact, orthogonal_factor, orthonormalize, polar_factor
from generator.geometry.nearest_rotation import nearest_reflection, nearest_rotation
from generator.scene.changes import rigid_fit

ROOT = Path(__file__).resolve().parents[1]
# no FMA; AVX2 + FMA; AVX-512: the kernels this machine can run (a stand-in cannot be a CPU
# with more than this one has); the x86-64 machines the README's commands are for run all three
CORES = tuple(core for core, needs in (("Sandybridge", "avx"), ("Haswell", "fma"), ("SkylakeX", "avx512f"))
              if needs in cpu_flags())
# the same three CPUs for numpy and the C library too
NUMPY_OFF = {"Sandybridge": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR", "Haswell": "X86_V4 AVX512_ICL AVX512_SPR",
             "SkylakeX": ""}
GLIBC_OFF = {"Sandybridge": "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F", "Haswell": "glibc.cpu.hwcaps=-AVX512F",
             "SkylakeX": ""}


def _stand_in(core: str) -> dict:
    """The environment that makes this machine's numpy, OpenBLAS and C library act as on ``core``."""
    return {"OPENBLAS_CORETYPE": core, "NPY_DISABLE_CPU_FEATURES": NUMPY_OFF[core], "GLIBC_TUNABLES": GLIBC_OFF[core],
            "PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}

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


def _digests(core: str, probe: str = PROBE) -> tuple[str, str]:
    out = subprocess.run([sys.executable, "-c", probe], env=_stand_in(core), cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    ours, numpys = out.stdout.split()
    return ours, numpys


def test_moving_parts_and_flow_motion_do_not_depend_on_the_blas_kernel():
    assert len(CORES) >= 2, f"this CPU stands in for only {CORES}: an x86-64 CPU with AVX2 and FMA is needed"
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


SITE_PROBE = """
import dataclasses, hashlib, math
import numpy as np
from generator.geometry.boxes import upright_box
from generator.scene.site import plan_site, site_params
from generator.scene.catalogue.trucks import route_poses
from trajectories import lawnmower, modified_random_walk, orbit, random_walk, spline_flythrough

ours, numpys = hashlib.sha256(), hashlib.sha256()


def feed(o):
    if isinstance(o, np.ndarray):
        ours.update(o.tobytes() if o.dtype != object else repr(o).encode())
    elif dataclasses.is_dataclass(o):
        for f in dataclasses.fields(o):
            feed(getattr(o, f.name))
    elif isinstance(o, dict):
        for k, v in o.items():
            feed(k), feed(v)
    elif isinstance(o, (list, tuple)):
        for v in o:
            feed(v)
    else:
        ours.update(repr(o).encode())


class Free:  # every move allowed: only the poses' arithmetic is compared
    def can_move(self, a, b):
        return True

    def is_free(self, p):
        return True


plan = plan_site(5, site_params("medium"))
feed(plan)
free, start = Free(), np.eye(4)
start[:3, 3] = (3.0, -2.0, 12.0)
for traj in (orbit(free, (1.5, -2.0), 37.0, 25.0, 40), spline_flythrough(free, ((-40, -40, 5), (40, 40, 30)), 40, np.random.default_rng(1)),
             lawnmower(free, ((-40, -30), (40, 30)), 30.0, 40, 12.0), random_walk(free, start, 40, np.random.default_rng(2)),
             modified_random_walk(free, start, 40, np.random.default_rng(3))):
    feed(traj.poses)
rng = np.random.default_rng(4)
for _ in range(30):
    box = upright_box(rng.normal(size=(200, 3)) * rng.uniform(0.5, 20, 3))
    q = rng.normal(size=4)
    w, a, b, c = q / np.sqrt((q * q).sum())  # a rotation made without BLAS or LAPACK
    m = np.eye(4)
    m[:3, :3] = np.array([[1 - 2 * (b * b + c * c), 2 * (a * b - c * w), 2 * (a * c + b * w)],
                          [2 * (a * b + c * w), 1 - 2 * (a * a + c * c), 2 * (b * c - a * w)],
                          [2 * (a * c - b * w), 2 * (b * c + a * w), 1 - 2 * (a * a + b * b)]]) * rng.uniform(0.5, 2)
    m[:3, 3] = rng.uniform(-100, 100, 3)
    feed(m), feed(box), feed(box.transformed(m))
feed(route_poses(plan.road, 5.0, 60, 10.0, 3.0))
x = rng.uniform(-30, 30, (4000, 3))
for a in (np.arctan2(x[:, 0], x[:, 1]), x[:, 2] ** 3, np.sin(x[:, 0] * 1e3), np.array([np.linalg.norm(v) for v in x])):
    numpys.update(a.tobytes())  # the control: numpy's own arctan2, power, sine and 1-D norms
print(ours.hexdigest(), numpys.hexdigest())
"""


def test_site_plans_trajectories_and_boxes_do_not_depend_on_the_cpu():
    """A site's plan (every asset's mesh, footprint and keyframes), the poses of all five
    trajectory kinds, 3D boxes and vehicle routes, under the three stand-in CPUs."""
    assert len(CORES) >= 2, f"this CPU stands in for only {CORES}: an x86-64 CPU with AVX2 and FMA is needed"
    digests = [_digests(core, SITE_PROBE) for core in CORES]
    assert len({ours for ours, _ in digests}) == 1, "a seed's geometry changes with the CPU's kernels"
    assert len({numpys for _, numpys in digests}) > 1, "the stand-ins did not change numpy and the C library"


def _rotation(rng) -> np.ndarray:
    q = rng.normal(size=4)
    w, x, y, z = q / np.sqrt((q * q).sum())
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_polar_factor_is_the_svds_nearest_orthogonal_matrix_and_falls_back_where_it_must():
    """camera.polar_factor (Newton, BLAS-free) against LAPACK's U V^T, and the matrices it
    refuses: the callers then take Horn's nearest rotation (or reflection)."""
    rng = np.random.default_rng(11)
    for k in range(60):
        a = _rotation(rng) @ np.diag(10.0 ** rng.uniform(-3, 3, 3)) @ _rotation(rng).T * (-1 if k % 3 == 0 else 1)
        a += rng.normal(size=(3, 3)) * 1e-3 * np.abs(a).max()
        u, _, vt = np.linalg.svd(a)
        p = polar_factor(a)
        assert np.abs(p - u @ vt).max() < 1e-12 and np.abs(p.T @ p - np.eye(3)).max() < 1e-14
    for bad in (np.diag([1.0, 1.0, 0.0]), _rotation(rng) @ np.diag([1.0, 1e12, 1.0]), np.full((3, 3), np.nan)):
        with pytest.raises(ValueError):
            polar_factor(bad)
    for a in (np.diag([1.0, 1.0, 0.0]), np.diag([2.0, 1.0, -1.0]), _rotation(rng) @ np.diag([1.0, 1e12, 1.0])):
        r = orthonormalize(a)
        assert np.abs(r.T @ r - np.eye(3)).max() < 1e-12 and np.linalg.det(r) > 0
        q = orthogonal_factor(a)
        assert np.abs(q.T @ q - np.eye(3)).max() < 1e-12
    flat = np.eye(4)
    flat[:3, :3] = 0.0  # an object scaled to nothing keeps a (zero) box
    box = Box3D(np.ones(3), np.ones(3), np.eye(3)).transformed(flat)
    assert np.array_equal(box.size, np.zeros(3)) and np.abs(box.rotation.T @ box.rotation - np.eye(3)).max() < 1e-12


@pytest.mark.parametrize("thickness", [0.0, 1e-7, 1e-3, 1.0])
def test_rigid_fit_recovers_a_rigid_move_of_flat_and_solid_parts(thickness):
    """The timeline's 'moved' test (generator/scene/changes.py) on parts from a flat sheet to a
    solid: the fitted rotation is the true one and the residual is round-off."""
    rng = np.random.default_rng(12)
    for _ in range(40):
        a = rng.uniform(-3, 3, (40, 3)) * [1.0, 1.0, thickness]
        a = a @ _rotation(rng).T + rng.uniform(-50, 50, 3)
        r, t = _rotation(rng), rng.uniform(-50, 50, 3)
        fit, residual = rigid_fit(a, a @ r.T + t)
        assert residual < 1e-9 and np.abs(fit[:3, :3] - r).max() < 1e-8 and np.abs(fit[:3, 3] - t).max() < 1e-7


def _svd_nearest(m: np.ndarray, det_sign: float) -> np.ndarray:
    """LAPACK's answer: U diag(1, 1, d) V^T with d making the determinant ``det_sign``."""
    u, _, vt = np.linalg.svd(m)
    d = det_sign * np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def test_nearest_rotation_and_reflection_are_the_svds_answers():
    """Horn's method with Jacobi rotations (generator/geometry/nearest_rotation.py) against
    the SVD on full-rank, mirrored, badly conditioned and flat matrices (where the answer is
    unique), and the largest trace(R^T M) where it is not (rank one, zero)."""
    rng = np.random.default_rng(13)
    for k in range(200):
        s = 10.0 ** rng.uniform(-3, 3, 3)
        if k % 4 == 1:
            s[2] = 0.0  # a flat point set's cross-covariance
        elif k % 4 == 2:
            s[1] *= 1e-9  # worse conditioned than polar_factor accepts
        m = _rotation(rng) @ np.diag(s) @ _rotation(rng).T * (-1 if k % 3 == 0 else 1) * 10.0 ** rng.uniform(-6, 6)
        for det_sign, ours in ((1.0, nearest_rotation(m)), (-1.0, nearest_reflection(m))):
            assert np.abs(ours.T @ ours - np.eye(3)).max() < 1e-14 and np.linalg.det(ours) * det_sign > 0
            ref = _svd_nearest(m, det_sign)
            gap = np.sort(s)  # the answer is unique unless two singular values tie at the bottom
            if gap[1] > 1e-6 * gap[2]:
                assert np.abs(ours - ref).max() < 1e-8, (k, det_sign)
            assert np.sum(ours * m) >= np.sum(ref * m) - 1e-12 * np.abs(m).sum()
    for m in (np.outer(rng.normal(size=3), rng.normal(size=3)), np.zeros((3, 3))):  # many answers: the best trace
        r = nearest_rotation(m)
        assert np.abs(r.T @ r - np.eye(3)).max() < 1e-14 and np.linalg.det(r) > 0
        assert np.sum(r * m) >= np.sum(_svd_nearest(m, 1.0) * m) - 1e-12
    assert np.array_equal(nearest_rotation(np.zeros((3, 3))), np.eye(3))
    with pytest.raises(ValueError):
        nearest_rotation(np.full((3, 3), np.inf))


FALLBACK_PROBE = """
import hashlib
import numpy as np
from generator.geometry.boxes import Box3D
from generator.geometry.camera import orthogonal_factor, orthonormalize, rows_times
from generator.scene.changes import rigid_fit

rng = np.random.default_rng(5)
ours, numpys = hashlib.sha256(), hashlib.sha256()
for k in range(100):
    q = rng.normal(size=(3, 3))
    flat = rng.uniform(-3, 3, (40, 3)) * [1.0, 1.0, 0.0 if k % 2 else 1e-9]  # a sheet: singular cross-covariance
    moved = rows_times(flat, orthonormalize(q).T) + rng.uniform(-50, 50, 3)
    fit, residual = rigid_fit(flat, moved)
    ours.update(fit.tobytes())
    m = np.eye(4)
    m[:3, :3] = q * [1.0, 0.0, 1.0]  # an object scaled to nothing along one axis
    ours.update(Box3D(np.ones(3), np.ones(3), np.eye(3)).transformed(m).rotation.tobytes())
    ours.update(orthogonal_factor(q * [1.0, 1.0, 0.0]).tobytes())
    ours.update(orthonormalize(-np.abs(q) - np.eye(3)).tobytes())  # a mirror
    numpys.update(np.linalg.svd(q * [1.0, 1.0, 0.0])[0].tobytes())  # the control: LAPACK's SVD
print(ours.hexdigest(), numpys.hexdigest())
"""


def test_the_rotation_fallbacks_do_not_depend_on_the_cpu():
    """Where polar_factor refuses a matrix (flat parts' rigid fits, boxes of objects scaled to
    nothing, mirrored matrices), the answer is still the same bits under the stand-in CPUs;
    LAPACK's SVD, which these used to take, is not."""
    assert len(CORES) >= 2, f"this CPU stands in for only {CORES}: an x86-64 CPU with AVX2 and FMA is needed"
    digests = [_digests(core, FALLBACK_PROBE) for core in CORES]
    assert len({ours for ours, _ in digests}) == 1, "a fallback's rotation changes with the CPU's kernels"
    assert len({numpys for _, numpys in digests}) > 1, "the stand-ins did not change LAPACK's SVD"


def test_rigid_fit_of_collinear_points_and_polar_factor_far_from_unit_scale():
    """Review findings: a cross-covariance of rank one (collinear points, two points) has
    cofactors and a determinant of round-off, which polar_factor must refuse (it used to
    return a wrong rotation: residuals of centimetres); matrices far from unit scale must not
    overflow into NaN; and orthogonal_factor must pick a reflection for a mirrored matrix at
    any scale (the sign of its determinant under- or overflows)."""
    rng = np.random.default_rng(14)
    for k in range(300):
        line = rng.normal(size=3)
        a = rng.uniform(-1, 1, (2 + k % 5, 1)) * line + rng.uniform(-20, 20, 3)
        r, t = _rotation(rng), rng.uniform(-50, 50, 3)
        fit, residual = rigid_fit(a, a @ r.T + t)
        assert np.isfinite(fit).all() and residual < 1e-9, (k, residual)
    for scale in (1e-300, 1e-200, 1e103, 1e200, 1e300):
        r = _rotation(rng)
        assert np.abs(polar_factor(scale * r) - r).max() < 1e-14
        mirror = r * [1.0, 1.0, -1.0]
        assert np.abs(orthogonal_factor(scale * mirror @ np.diag([1.0, 1e-10, 1.0])) - mirror).max() < 1e-9
        if scale < 1e150:  # (beyond, the residual's squares overflow: no point sets of that size)
            fit, _ = rigid_fit(scale * rng.normal(size=(10, 3)), np.zeros((10, 3)))
            assert np.isfinite(fit).all()
