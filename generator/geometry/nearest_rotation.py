"""The rotation nearest to any 3x3 matrix, in the same bits on every CPU.

:func:`nearest_rotation` gives the rotation R that maximises trace(R^T M) (the nearest to M
in the Frobenius norm among rotations; for a cross-covariance, the Kabsch rotation) for any
finite M: singular (a flat or collinear point set, an object scaled to nothing), mirrored
or badly conditioned. It is Horn's quaternion method: the unit quaternion of R is the
eigenvector of a 4x4 symmetric matrix built from M for its largest eigenvalue, found here
by cyclic Jacobi rotations in Python floats (IEEE float64 multiplies, adds, divides and
square roots, in a fixed order; no BLAS, no LAPACK, no fused multiply-add), so the result
does not depend on the CPU, unlike LAPACK's SVD, whose kernels OpenBLAS picks by CPU
(docs/guarantees.md, "Same bytes"). :func:`camera.polar_factor` remains the first choice
where it applies (it keeps the bits of earlier releases); this is where it does not.

Where the largest eigenvalue is repeated the answer is not unique (M of rank one or zero:
every rotation about the one direction, or every rotation, is as near): the first of the
tied eigenvectors in Jacobi's order is taken, the same on every machine (M = 0 gives the
identity).
"""

from __future__ import annotations

import math

import numpy as np

SWEEPS = 60  # Jacobi converges quadratically: 4x4 matrices settle in 5-8 sweeps


def _horn_matrix(m: list[list[float]]) -> list[list[float]]:
    """Horn's symmetric N with q^T N q = trace(R(q)^T M) for unit quaternions q = (w, x, y, z)."""
    (xx, xy, xz), (yx, yy, yz), (zx, zy, zz) = m
    return [[xx + yy + zz, zy - yz, xz - zx, yx - xy],
            [zy - yz, xx - yy - zz, xy + yx, xz + zx],
            [xz - zx, xy + yx, yy - xx - zz, yz + zy],
            [yx - xy, xz + zx, yz + zy, zz - xx - yy]]


def _rotate(a: list[list[float]], v: list[list[float]], p: int, q: int) -> None:
    """One Jacobi rotation zeroing a[p][q] (a symmetric, v the eigenvectors' columns)."""
    apq = a[p][q]
    theta = (a[q][q] - a[p][p]) / (2.0 * apq)
    if abs(theta) > 1e150:  # theta^2 would overflow: t = 1 / (2 theta) to double precision
        t = 0.5 / theta
    else:
        t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
        if theta < 0:
            t = -t
    c = 1.0 / math.sqrt(t * t + 1.0)
    s = t * c
    tau = s / (1.0 + c)
    a[p][p] -= t * apq
    a[q][q] += t * apq
    a[p][q] = a[q][p] = 0.0
    for r in range(4):
        if r != p and r != q:
            arp, arq = a[r][p], a[r][q]
            a[r][p] = a[p][r] = arp - s * (arq + tau * arp)
            a[r][q] = a[q][r] = arq + s * (arp - tau * arq)
        vrp, vrq = v[r][p], v[r][q]
        v[r][p] = vrp - s * (vrq + tau * vrp)
        v[r][q] = vrq + s * (vrp - tau * vrq)


def _top_eigenvector_4(n: list[list[float]]) -> list[float]:
    """Unit eigenvector of a symmetric 4x4 matrix (lists of floats, entries of order 1: the
    caller scales them) for its largest eigenvalue (the first in index order where several
    tie), by cyclic Jacobi sweeps."""
    a = [list(map(float, row)) for row in n]
    v = [[1.0 if i == j else 0.0 for j in range(4)] for i in range(4)]
    scale = sum(x * x for row in a for x in row)
    for _ in range(SWEEPS):
        off = sum(a[p][q] * a[p][q] for p in range(3) for q in range(p + 1, 4))
        if off <= scale * 1e-36:  # off-diagonal at round-off: the diagonal holds the eigenvalues
            break
        for p in range(3):
            for q in range(p + 1, 4):
                if a[p][q] != 0.0:
                    _rotate(a, v, p, q)
    k = max(range(4), key=lambda i: (a[i][i], -i))
    col = [v[r][k] for r in range(4)]
    length = math.sqrt(sum(x * x for x in col))
    return [x / length for x in col]


def quaternion_matrix(q: list[float]) -> np.ndarray:
    """3x3 rotation of the unit quaternion (w, x, y, z), in a fixed order of IEEE operations."""
    w, x, y, z = q
    return np.array([[w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
                     [2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x)],
                     [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z]])


def nearest_rotation(m: np.ndarray) -> np.ndarray:
    """The 3x3 rotation R (det +1) maximising trace(R^T m), for any finite 3x3 ``m``."""
    m = np.asarray(m, dtype=np.float64)
    if m.shape != (3, 3) or not np.isfinite(m).all():
        raise ValueError(f"nearest_rotation needs a finite 3x3 matrix, got shape {m.shape}")
    peak = float(np.abs(m).max())
    if peak == 0.0:
        return np.eye(3)
    # by a power of two: the entries keep their bits and their squares stay in range
    m = np.ldexp(m, -math.frexp(peak)[1])
    return quaternion_matrix(_top_eigenvector_4(_horn_matrix(m.tolist())))


def nearest_reflection(m: np.ndarray) -> np.ndarray:
    """The 3x3 orthogonal matrix with determinant -1 maximising trace(Q^T m): R D with R the
    rotation nearest to m D, D = diag(1, 1, -1)."""
    d = np.array([1.0, 1.0, -1.0])
    return nearest_rotation(np.asarray(m, dtype=np.float64) * d) * d
