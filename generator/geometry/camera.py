"""Pinhole camera model and pose conventions (the single implementation used everywhere).

Conventions (docs/conventions.md):
- World: right-handed, Z up, metres.
- Camera frame: OpenCV/COLMAP, x right, y down, z forward. Blender's camera frame is this
  one rotated 180 degrees about x.
- Poses are ``world_from_camera`` 4x4 matrices (camera-to-world).
- Pixels: the image's top-left corner is (0, 0); the centre of pixel (row i, col j) is
  (j + 0.5, i + 0.5). ``K`` maps camera coordinates to these continuous pixel coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..checks import MAX_COORDINATE
from . import portable_math
from .nearest_rotation import nearest_reflection, nearest_rotation

# Blender camera frame (x right, y up, z backward) -> OpenCV camera frame.
CV_FROM_BLENDER_CAMERA = np.diag([1.0, -1.0, -1.0, 1.0])

RIGID_TOLERANCE = 1e-5


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics: image size in pixels and the 3x3 matrix ``K`` (pixels)."""

    width: int
    height: int
    K: np.ndarray

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])


def intrinsics_from_blender(
    width: int,
    height: int,
    lens_mm: float,
    sensor_width_mm: float,
    sensor_height_mm: float,
    sensor_fit: str,
    shift_x: float = 0.0,
    shift_y: float = 0.0,
    pixel_aspect_x: float = 1.0,
    pixel_aspect_y: float = 1.0,
) -> Intrinsics:
    """K of a Blender perspective camera for a render of ``width`` x ``height`` pixels.

    Follows Blender's own rules: with ``AUTO`` fit the sensor width spans the larger image
    dimension; ``HORIZONTAL`` / ``VERTICAL`` span the width / height. Lens shift is in units
    of the larger (fitted) image dimension, positive x right and positive y up.
    """
    if width <= 0 or height <= 0:
        raise ValueError(f"image size must be positive, got {width}x{height}")
    if lens_mm <= 0:
        raise ValueError(f"focal length must be positive, got {lens_mm} mm")
    aspect = pixel_aspect_x / pixel_aspect_y  # pixel width / pixel height
    if sensor_fit == "AUTO":
        fit = "HORIZONTAL" if width * pixel_aspect_x >= height * pixel_aspect_y else "VERTICAL"
        sensor_mm = sensor_width_mm
    elif sensor_fit == "HORIZONTAL":
        fit, sensor_mm = "HORIZONTAL", sensor_width_mm
    elif sensor_fit == "VERTICAL":
        fit, sensor_mm = "VERTICAL", sensor_height_mm
    else:
        raise ValueError(f"unknown sensor fit {sensor_fit!r}")
    # Number of (horizontal-unit) pixels spanned by the sensor: a row is 1 / aspect of them
    # (Blender's viewplane: ycor * winy with ycor = pixel_aspect_y / pixel_aspect_x).
    view_px = width if fit == "HORIZONTAL" else height / aspect
    fx = lens_mm / sensor_mm * view_px
    fy = fx * aspect
    cx = width / 2.0 - shift_x * view_px
    cy = height / 2.0 + shift_y * view_px * aspect
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return Intrinsics(int(width), int(height), K)


SITE_LENS_MM, SITE_SENSOR_MM = 20.0, 36.0  # the generated sites' camera (generator/blender/build.py)


def site_intrinsics(width: int, height: int) -> Intrinsics:
    """K of the generated sites' camera for a ``width`` x ``height`` render."""
    return intrinsics_from_blender(width, height, SITE_LENS_MM, SITE_SENSOR_MM, SITE_SENSOR_MM, "AUTO")


def orthonormalize(rotation: np.ndarray) -> np.ndarray:
    """Closest rotation matrix (polar decomposition) to a 3x3 matrix; removes scale. For a
    rotation times a well-conditioned scale (every matrix of a Blender object without a
    mirror) it is :func:`polar_factor`; a mirror, a singular or a badly conditioned matrix
    goes to :func:`nearest_rotation.nearest_rotation` (a mirror gives the rotation nearest to
    it, not a reflection). Both give the same bits on every CPU."""
    try:
        q = polar_factor(rotation)
        if _cofactors_3x3(q)[1] > 0:
            return q
    except ValueError:
        pass
    return nearest_rotation(rotation)


def orthogonal_factor(a: np.ndarray) -> np.ndarray:
    """The orthogonal matrix nearest to a 3x3 matrix (U V^T of its SVD), the same bits on
    every CPU: :func:`polar_factor` where it applies; for the singular or badly conditioned
    matrices it refuses, the nearer of the nearest rotation and the nearest reflection by
    Horn's method (:mod:`.nearest_rotation`). A singular matrix has several nearest
    orthogonal matrices: the rotation among them is taken."""
    try:
        return polar_factor(a)
    except ValueError:
        pass
    rotation, reflection = nearest_rotation(a), nearest_reflection(a)
    # the nearer of the two (the larger trace(Q^T a)), a reflection only when nearer by more
    # than round-off; not by the sign of the determinant, which is round-off for a nearly
    # singular matrix and under- or overflows far from 1
    a = np.asarray(a, dtype=np.float64)
    nearer = np.sum(reflection * a) > np.sum(rotation * a) + 1e-12 * np.sum(np.abs(a))
    return reflection if nearer else rotation


def _cofactors_3x3(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cofactor matrices, determinants) of 3x3 matrices (..., 3, 3) in a fixed order of IEEE
    operations; the cofactors over the determinant are the inverse transpose."""
    a = np.asarray(a, dtype=np.float64)
    cof = np.empty(a.shape)
    for i in range(3):
        for j in range(3):
            i1, i2, j1, j2 = (i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3
            cof[..., i, j] = a[..., i1, j1] * a[..., i2, j2] - a[..., i1, j2] * a[..., i2, j1]
    det = (a[..., 0, 0] * cof[..., 0, 0] + a[..., 0, 1] * cof[..., 0, 1]) + a[..., 0, 2] * cof[..., 0, 2]
    return cof, det


POLAR_MAX_CONDITION = 1e8  # ||a||_F ||a^-1||_F above this: polar_factor refuses the matrix


def _frobenius(a: np.ndarray) -> float:
    return float(np.sqrt(np.sum(a * a)))


def polar_factor(a: np.ndarray, iterations: int = 60) -> np.ndarray:
    """The orthogonal matrix nearest to an invertible 3x3 matrix (U V^T of its SVD: a rotation
    when the determinant is positive) by Newton's iteration with Higham's scaling,
    X <- (g X + X^-T / g) / 2 with g = sqrt(|X^-1|_F / |X|_F), then unscaled steps until X
    stops changing; IEEE operations in a fixed order, so the same bits on every CPU (LAPACK's
    SVD picks its kernel by CPU). Raises ValueError for a matrix that is not finite, singular
    or worse conditioned than POLAR_MAX_CONDITION, or if the result is not orthogonal to
    1e-12 (callers fall back to the SVD: :func:`orthogonal_factor`)."""
    x = np.array(a, dtype=np.float64)
    if x.shape != (3, 3) or not np.isfinite(x).all():
        raise ValueError("polar_factor needs a finite 3x3 matrix")
    peak = float(np.abs(x).max())
    if peak > math.ldexp(1.0, 100) or 0 < peak < math.ldexp(1.0, -100):
        # far from 1 the cofactors would over- or underflow: scale by a power of two (exact),
        # which the polar factor ignores
        x = np.ldexp(x, -math.frexp(peak)[1])
    cof, det = _cofactors_3x3(x)
    size = _frobenius(x)
    # (the second test: cofactors far below |x|^2 mean a matrix of rank one to round-off, whose
    # cofactors and determinant are both noise, so that the condition estimate can look fine)
    if (det == 0 or not np.isfinite(cof / det).all() or size * _frobenius(cof / det) > POLAR_MAX_CONDITION
            or not _frobenius(cof) >= size * size / POLAR_MAX_CONDITION):
        raise ValueError("polar_factor needs an invertible, well-conditioned 3x3 matrix")
    for k in range(iterations):
        cof, det = _cofactors_3x3(x)
        inv_t = cof / det
        g = np.sqrt(_frobenius(inv_t) / _frobenius(x)) if k < 8 else 1.0  # scaling only while far off
        nxt = 0.5 * (g * x + inv_t / g)
        if np.array_equal(nxt, x):
            break
        x = nxt
    if not np.abs(matmul_exact(x.T, x) - np.eye(3)).max() <= 1e-12:  # (NaN fails too: overflow)
        raise ValueError("polar_factor did not converge (a badly conditioned matrix)")
    return x


def world_from_camera_from_blender(matrix_world: np.ndarray) -> np.ndarray:
    """OpenCV ``world_from_camera`` from a Blender camera object's ``matrix_world``.

    Scale on the Blender camera object does not change its projection, so it is removed.
    """
    m = np.asarray(matrix_world, dtype=np.float64)
    out = np.eye(4)
    out[:3, :3] = orthonormalize(m[:3, :3])
    out[:3, 3] = m[:3, 3]
    return out @ CV_FROM_BLENDER_CAMERA


def blender_from_world_from_camera(world_from_camera: np.ndarray) -> np.ndarray:
    """Blender camera ``matrix_world`` for an OpenCV ``world_from_camera`` pose."""
    return np.asarray(world_from_camera, dtype=np.float64) @ CV_FROM_BLENDER_CAMERA


def validate_rigid(matrix: np.ndarray, tolerance: float = RIGID_TOLERANCE) -> np.ndarray:
    """Return ``matrix`` as a float64 4x4 rigid transform, or raise ValueError saying why not."""
    try:
        m = np.asarray(matrix, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"pose must be a 4x4 matrix of real numbers, got {matrix!r:.60}") from None
    if m.shape != (4, 4):
        raise ValueError(f"pose must be a 4x4 matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ValueError("pose contains NaN or inf")
    if np.abs(m[:3, 3]).max() > MAX_COORDINATE:
        raise ValueError(f"pose's camera centre {m[:3, 3].tolist()} is farther than {MAX_COORDINATE:.0e} m from the origin")
    if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], atol=tolerance):
        raise ValueError(f"pose's last row must be [0, 0, 0, 1], got {m[3].tolist()}")
    r = m[:3, :3]
    if not np.allclose(r.T @ r, np.eye(3), atol=tolerance):
        raise ValueError("pose's rotation block is not orthonormal (scale or shear); pass a rigid transform")
    if np.linalg.det(r) < 0:
        raise ValueError("pose's rotation block has determinant -1 (a reflection); pass a rigid transform")
    return m


def invert_rigid(m: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform: the rotation transposed and -R^T t, without BLAS (the
    same bits on every CPU, :func:`rows_times`)."""
    out = np.eye(4)
    r = np.asarray(m[:3, :3], dtype=np.float64)
    out[:3, :3] = r.T
    out[:3, 3] = -rows_times(m[:3, 3], r)
    return out


def world_to_camera(points_world: np.ndarray, world_from_camera: np.ndarray) -> np.ndarray:
    """Points (N, 3) from world to OpenCV camera coordinates."""
    r = world_from_camera[:3, :3]
    t = world_from_camera[:3, 3]
    return rows_times(np.asarray(points_world) - t, r)  # BLAS-free: the same bits on every CPU


def project(points_world: np.ndarray, world_from_camera: np.ndarray, K: np.ndarray, lens=None):
    """Project world points: returns pixel coordinates (N, 2) as (x, y) and planar depth z (N,),
    through ``lens`` (generator/geometry/lens.py) where it distorts.

    Points behind the camera get z <= 0 and meaningless pixel coordinates (NaN through a
    distorting lens).
    """
    return project_camera_points(world_to_camera(points_world, world_from_camera), K, lens)


def project_camera_points(pc: np.ndarray, K: np.ndarray, lens=None):
    """:func:`project` of points (N, 3) already in OpenCV camera coordinates."""
    if lens is not None and not lens.ideal:
        return lens.project(K, pc)
    z = pc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = K[0, 0] * pc[:, 0] / z + K[0, 1] * pc[:, 1] / z + K[0, 2]
        v = K[1, 1] * pc[:, 1] / z + K[1, 2]
    return np.stack([u, v], axis=1), z


def rows_times(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``v @ m`` for vectors v (..., 3) and a 3x3 ``m`` (or ``m`` (N, 3, 3) against v (N, 3),
    row by row), float64, as (v0 m0k + v1 m1k) + v2 m2k in IEEE arithmetic. numpy hands
    ``@`` to BLAS, whose kernel, and so its rounding, depends on the CPU: ground truth that
    must be the same bytes on every machine goes through here (generator/geometry/exact_kernels.py)."""
    from . import exact_kernels  # numba: loaded on first use, not by every reader of this module

    v, m = np.asarray(v, dtype=np.float64), np.ascontiguousarray(m, dtype=np.float64)
    flat = np.ascontiguousarray(v.reshape(-1, 3))
    out = np.empty(flat.shape)
    (exact_kernels.batch_rows_times if m.ndim == 3 else exact_kernels.rows_times)(flat, m, out)
    return out.reshape(v.shape)


def apply_affine(m: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (..., 3) moved by the 4x4 affine ``m`` (p R^T + t), float64, BLAS-free: the same
    bits on every CPU (:func:`rows_times`)."""
    m = np.asarray(m, dtype=np.float64)
    return rows_times(points, m[:3, :3].T) + m[:3, 3]


def turn_normals(m: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Unit normals (N, 3) carried by the 4x4 affine ``m`` (the inverse-transpose of its 3x3
    part, so scale and mirrors are right), made unit length again (zero stays zero);
    BLAS- and LAPACK-free (:func:`affine_inverse`)."""
    n = rows_times(normals, affine_inverse(m)[:3, :3])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)


def matmul_exact(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for stacks of small matrices (..., n, k) and (..., k, m), float64, summed over
    k in order with separate IEEE multiplies and adds (numpy element-wise operations, never
    BLAS): the same bits on every CPU, as :func:`rows_times`."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    out = a[..., :, 0, None] * b[..., None, 0, :]
    for k in range(1, a.shape[-1]):
        out = out + a[..., :, k, None] * b[..., None, k, :]
    return out


def affine_inverse(m: np.ndarray) -> np.ndarray:
    """Inverse of invertible affine matrices (..., 4, 4) (last row 0 0 0 1), float64, from the
    adjugate of the 3x3 part in a fixed order of IEEE operations: the same bits on every CPU
    (``np.linalg.inv`` hands the work to LAPACK, whose kernel depends on the CPU). Accurate to
    float64 round-off for the well-conditioned matrices of rigid and scaled objects."""
    m = np.asarray(m, dtype=np.float64)
    cof, det = _cofactors_3x3(m[..., :3, :3])
    out = np.zeros(m.shape)
    out[..., :3, :3] = np.swapaxes(cof, -1, -2) / det[..., None, None]
    t = m[..., :3, 3]
    for i in range(3):
        out[..., i, 3] = -((out[..., i, 0] * t[..., 0] + out[..., i, 1] * t[..., 1]) + out[..., i, 2] * t[..., 2])
    out[..., 3, 3] = 1.0
    return out


def pixel_rays(K: np.ndarray, width: int, height: int) -> np.ndarray:
    """Camera-frame directions (H, W, 3) through pixel centres, scaled so that z = 1."""
    j, i = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    y = (i - K[1, 2]) / K[1, 1]
    x = (j - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return np.stack([x, y, np.ones_like(x)], axis=-1)


def depth_to_world_points(depth: np.ndarray, K: np.ndarray, world_from_camera: np.ndarray, lens=None) -> np.ndarray:
    """Unproject a planar depth map (H, W) in metres to world points (H, W, 3).

    Each pixel is unprojected through its centre (along the ray of ``lens``,
    generator/geometry/lens.py, where given). Pixels with non-finite or non-positive depth
    (no surface) give NaN.
    """
    depth = np.asarray(depth, dtype=np.float64)
    if depth.ndim != 2:
        raise ValueError(f"depth must be a 2D (H, W) array, got shape {depth.shape}")
    h, w = depth.shape
    rays = pixel_rays(K, w, h) if lens is None else lens.rays(K, w, h)
    valid = np.isfinite(depth) & (depth > 0)
    pc = rays * np.where(valid, depth, np.nan)[..., None]
    return apply_affine(world_from_camera, pc)  # BLAS-free: the same bits on every CPU


def translated_along_axis(world_from_camera: np.ndarray, axis: int, distance: float) -> np.ndarray:
    """The pose moved by ``distance`` metres along its own camera axis (0: x right,
    1: y down, 2: z forward)."""
    m = np.array(world_from_camera, dtype=np.float64)
    m[:3, 3] += distance * m[:3, axis]
    return m


def turned_about_world_z(world_from_camera: np.ndarray, angle: float) -> np.ndarray:
    """The pose turned right (clockwise seen from above) by ``angle`` radians about the
    world Z axis through its centre; the horizon stays level."""
    s, c = portable_math.sincos(-angle)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    m = np.array(world_from_camera, dtype=np.float64)
    m[:3, :3] = matmul_exact(rz, m[:3, :3])
    return m


def heading_pose(position, yaw: float, pitch: float) -> np.ndarray:
    """world_from_camera at ``position`` looking along heading ``yaw`` (radians from +X,
    counter-clockwise seen from above) and ``pitch`` (radians above the horizon), zero roll."""
    (sp, cp), (sy, cy) = portable_math.sincos(pitch), portable_math.sincos(yaw)  # the same bits on every CPU
    forward = np.array([cp * cy, cp * sy, sp])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= portable_math.vector_norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(forward, right), forward, position
    return m


def levelled(pose: np.ndarray) -> np.ndarray:
    """The same position and heading with the camera level (zero pitch and roll)."""
    forward = np.asarray(pose)[:3, 2]
    return heading_pose(np.asarray(pose)[:3, 3], portable_math.atan2(forward[1], forward[0]), 0.0)


def look_at(eye, target) -> np.ndarray:
    """world_from_camera at ``eye`` looking at ``target`` with zero roll (not straight down)."""
    d = np.asarray(target, dtype=np.float64) - np.asarray(eye, dtype=np.float64)
    return heading_pose(eye, portable_math.atan2(d[1], d[0]), portable_math.atan2(d[2], portable_math.hypot(d[0], d[1])))
