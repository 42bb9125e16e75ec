"""Occlusion tests of SceneGeometry.rays_blocked (rule 4's rays, collision and observability):
the same answers as an independent float64 segment test, from both sides of a triangle,
watertight at a vertex many triangles share, on float64 and strided input, through the
static and the dynamic structure, and after dynamic parts move."""

import numpy as np
import pytest

from generator import Simulator  # noqa: F401  (bpy before open3d)
from generator.geometry.parts import MeshPart
from generator.geometry.raycast import SceneGeometry
from generator.scene.meshes import MeshBuilder
from exact_geometry import first_hits
from part_builder import mesh_part


def _turn(angle: float, centre) -> np.ndarray:
    """world_from_object: a turn of ``angle`` radians about z, then a shift to ``centre``."""
    c, s = np.cos(angle), np.sin(angle)
    m = np.eye(4)
    m[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    m[:3, 3] = centre
    return m


@pytest.fixture(scope="module")
def parts():
    """Boxes (closed; two of them dynamic, turned and shifted by their matrices), an open
    single-sided ground and a free-standing wall (one-sided quads)."""
    rng = np.random.default_rng(3)
    out = [mesh_part("Ground", MeshBuilder().add([(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], [(0, 1, 2, 3)])),
           mesh_part("Wall", MeshBuilder().add([(-5, 4, 0), (5, 4, 0), (5, 4, 6), (-5, 4, 6)], [(0, 1, 2, 3)]))]
    for k in range(12):
        size = tuple(rng.uniform(0.5, 3.0, 3))
        centre = (*rng.uniform(-12, 12, 2), size[2] / 2 + rng.uniform(0, 2))
        if k < 2:
            out.append(mesh_part(f"Box{k}", MeshBuilder().box(size), dynamic=True, matrix=_turn(0.4 + k, centre)))
        else:
            out.append(mesh_part(f"Box{k}", MeshBuilder().box(size, centre)))
    return out


def _world_triangles(parts) -> np.ndarray:
    """(T, 3, 3) float64 corners of every triangle, placed by each part's matrix in plain
    numpy (not MeshPart.world_vertices), rounded to the float32 values the structure holds."""
    out = []
    for p in parts:
        world = p.vertices @ p.matrix[:3, :3].T + p.matrix[:3, 3]
        out.append(world.astype(np.float32).astype(np.float64)[p.faces])
    return np.concatenate(out)


def _random_rays(rng, n):
    """float32 segments (N, 6) [origin, direction] between random points of the scene's volume."""
    a = rng.uniform((-18, -18, -3), (18, 18, 9), (n, 3))
    b = rng.uniform((-18, -18, -3), (18, 18, 9), (n, 3))
    return np.concatenate([a, b - a], axis=1).astype(np.float32)


def test_same_answers_as_float64_segments(parts):
    rays = _random_rays(np.random.default_rng(0), 3000)
    got = SceneGeometry(parts).rays_blocked(rays)
    o, d = rays[:, :3].astype(np.float64), rays[:, 3:].astype(np.float64)
    t, _ = first_hits(o, d, _world_triangles(parts))
    margin = 1e-4 / np.linalg.norm(d, axis=1)  # 0.1 mm, as a share of each segment
    clear = ~(np.abs(t - 1) < margin) & ~(t < margin)  # the first hit clear of both ends
    want = t <= 1
    assert clear.sum() > 2900 and 0.2 < want.mean() < 0.9  # a real mix of blocked and clear segments
    np.testing.assert_array_equal(got[clear], want[clear])


def test_a_triangle_blocks_from_both_sides():
    tri = MeshPart("t", "t", np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0.0]]), np.array([[0, 1, 2]]))
    down = [0.5, 0.5, 1, 0, 0, -2]  # sees the front (counter-clockwise from above)
    up = [0.5, 0.5, -1, 0, 0, 2]  # sees the back
    short = [0.5, 0.5, 1, 0, 0, -0.9]  # stops before the triangle
    beside = [3, 3, 1, 0, 0, -2]
    for dynamic in (False, True):
        part = MeshPart(tri.name, tri.label, tri.vertices, tri.faces, dynamic=dynamic)
        got = SceneGeometry([part]).rays_blocked(np.array([down, up, short, beside], np.float32))
        assert got.tolist() == [True, True, False, False]


def test_a_shared_vertex_is_watertight():
    """Rays exactly through the vertex that the 64 triangles of a tilted fan share, from
    random directions on both sides, are all blocked: the structure is built robust (with
    Embree's default, non-robust build a share of them passes between the triangles: measured
    in docs/benchmarks.md, "What was tried and rejected")."""
    k = 64
    angles = np.linspace(0, 2 * np.pi, k, endpoint=False)
    rim = np.stack([3 * np.cos(angles), 3 * np.sin(angles), np.zeros(k)], axis=1)
    c, s = np.cos(0.37), np.sin(0.37)
    tilt = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    vertices = (np.concatenate([[[0.0, 0.0, 0.0]], rim]) @ tilt.T + (0.3, -0.2, 5.0)).astype(np.float32)
    fan = MeshPart("fan", "fan", vertices.astype(np.float64), np.array([[0, 1 + i, 1 + (i + 1) % k] for i in range(k)]))
    rng = np.random.default_rng(11)
    n = 2048
    origins = (vertices[0] + rng.normal(0, 4, (n, 3)) + (0, 0, 6) * rng.choice([-1, 1], (n, 1))).astype(np.float32)
    rays = np.concatenate([origins, 2 * (vertices[0] - origins)], axis=1).astype(np.float32)  # past the vertex
    assert SceneGeometry([fan]).rays_blocked(rays).all()


def test_float64_and_strided_input(parts):
    rays = _random_rays(np.random.default_rng(9), 400)
    geometry = SceneGeometry(parts)
    want = geometry.rays_blocked(rays)
    wide = np.zeros((400, 12))
    wide[:, ::2] = rays  # float64, every other column
    np.testing.assert_array_equal(geometry.rays_blocked(wide[:, ::2]), want)
    assert len(geometry.rays_blocked(rays[:0])) == 0


def test_rays_blocked_follows_moving_parts(parts):
    crate = mesh_part("Crate", MeshBuilder().box((1.0, 1.0, 1.0), (0.0, 0.0, 0.0)), dynamic=True)
    geometry = SceneGeometry(parts[:1] + [crate])  # ground and a moving crate
    ray = np.array([[0, -10, 2, 0, 20, 0]], np.float32)  # 2 m above the ground, along +y
    assert not geometry.rays_blocked(ray)[0]
    geometry.set_matrices({1: np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 2.0], [0, 0, 0, 1]])})
    assert geometry.rays_blocked(ray)[0]
    geometry.set_matrices({1: np.eye(4)})
    assert not geometry.rays_blocked(ray)[0]
