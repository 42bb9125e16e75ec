"""Occlusion tests straight into Embree (generator/geometry/embree.py): the same answers as
an independent float64 segment test and as open3d's ``test_occlusions``, from both sides of
a triangle, on any number of threads and packet fillings, through several scenes in turn,
and after dynamic parts move (SceneGeometry.rays_blocked)."""

import numba
import numpy as np
import pytest

from generator import Simulator  # noqa: F401  (bpy before open3d)
from generator.geometry import embree
from generator.geometry.o3d import import_open3d
from generator.geometry.parts import MeshPart, closed_and_orientation
from generator.geometry.raycast import SceneGeometry
from generator.scene.meshes import MeshBuilder
from exact_geometry import first_hits, scene_triangles


def _part(name, builder, **kw):
    d = builder.build()
    tris = np.concatenate([d.quads[:, [0, 1, 2]], d.quads[:, [0, 2, 3]], d.tris]) if len(d.quads) else d.tris
    closed, outward = closed_and_orientation(d.vertices, tris)
    return MeshPart(name, name, d.vertices, tris, closed=closed, outward=outward, **kw)


@pytest.fixture(scope="module")
def parts():
    """Boxes (closed), an open single-sided ground and a free-standing wall (one-sided quads)."""
    rng = np.random.default_rng(3)
    out = [_part("Ground", MeshBuilder().add([(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], [(0, 1, 2, 3)])),
           _part("Wall", MeshBuilder().add([(-5, 4, 0), (5, 4, 0), (5, 4, 6), (-5, 4, 6)], [(0, 1, 2, 3)]))]
    for k in range(12):
        size = tuple(rng.uniform(0.5, 3.0, 3))
        centre = (*rng.uniform(-12, 12, 2), size[2] / 2 + rng.uniform(0, 2))
        out.append(_part(f"Box{k}", MeshBuilder().box(size, centre)))
    return out


def _random_rays(rng, n):
    """float32 segments (N, 6) [origin, direction] between random points of the scene's volume."""
    a = rng.uniform((-18, -18, -3), (18, 18, 9), (n, 3))
    b = rng.uniform((-18, -18, -3), (18, 18, 9), (n, 3))
    return np.concatenate([a, b - a], axis=1).astype(np.float32)


def _reference(rays, triangles):
    """float64 answers of the float32 segments, and which are clear of round-off (the first
    hit not within 1e-5 of either end)."""
    o, d = rays[:, :3].astype(np.float64), rays[:, 3:].astype(np.float64)
    t, _ = first_hits(o, d, triangles)
    clear = ~(np.abs(t - 1) < 1e-5) & ~(t < 1e-5)
    return t <= 1, clear


def test_same_answers_as_float64_segments_and_open3d(parts):
    rng = np.random.default_rng(0)
    rays = _random_rays(rng, 3000)
    scene = embree.OcclusionScene(parts)
    got = embree.occluded([scene], rays)
    want, clear = _reference(rays, scene_triangles(parts))
    assert clear.sum() > 2900 and 0.2 < want.mean() < 0.9  # a real mix of blocked and clear segments
    np.testing.assert_array_equal(got[clear], want[clear])
    o3d = import_open3d()
    reference = o3d.t.geometry.RaycastingScene()
    for p in parts:
        reference.add_triangles(np.ascontiguousarray(p.world_vertices(), np.float32), p.faces.astype(np.uint32))
    theirs = reference.test_occlusions(o3d.core.Tensor.from_numpy(rays), tnear=0.0, tfar=1.0).numpy().astype(bool)
    np.testing.assert_array_equal(got, theirs)


def test_a_triangle_blocks_from_both_sides():
    tri = MeshPart("t", "t", np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0.0]]), np.array([[0, 1, 2]]))
    scene = embree.OcclusionScene([tri])
    down = [0.5, 0.5, 1, 0, 0, -2]  # sees the front (counter-clockwise from above)
    up = [0.5, 0.5, -1, 0, 0, 2]  # sees the back
    short = [0.5, 0.5, 1, 0, 0, -0.9]  # stops before the triangle
    beside = [3, 3, 1, 0, 0, -2]
    got = embree.occluded([scene], np.array([down, up, short, beside], np.float32))
    assert got.tolist() == [True, True, False, False]


@pytest.mark.parametrize("n", [1, 7, 8, 9, 1001])
def test_answers_do_not_depend_on_threads_or_packet_filling(parts, n):
    rays = _random_rays(np.random.default_rng(n), n)
    scene = embree.OcclusionScene(parts)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = embree.occluded([scene], rays)
    finally:
        numba.set_num_threads(threads)
    every = embree.occluded([scene], rays)
    alone = np.array([embree.occluded([scene], rays[i:i + 1])[0] for i in range(n)])
    np.testing.assert_array_equal(one, every)
    np.testing.assert_array_equal(alone, every)


def test_scenes_in_turn_and_empty_scenes(parts):
    rays = _random_rays(np.random.default_rng(5), 500)
    first, second = embree.OcclusionScene(parts[:7]), embree.OcclusionScene(parts[7:])
    empty = embree.OcclusionScene([])
    both = embree.occluded([first, empty, second], rays)
    np.testing.assert_array_equal(both, embree.occluded([first], rays) | embree.occluded([second], rays))
    assert not embree.occluded([empty], rays).any() and len(embree.occluded([first], rays[:0])) == 0


def test_rays_blocked_follows_moving_parts(parts):
    crate = _part("Crate", MeshBuilder().box((1.0, 1.0, 1.0), (0.0, 0.0, 0.0)), dynamic=True)
    geometry = SceneGeometry(parts[:1] + [crate])  # ground and a moving crate
    ray = np.array([[0, -10, 2, 0, 20, 0]], np.float32)  # 2 m above the ground, along +y
    assert not geometry.rays_blocked(ray)[0]
    geometry.set_matrices({1: np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 2.0], [0, 0, 0, 1]])})
    assert geometry.rays_blocked(ray)[0]
    geometry.set_matrices({1: np.eye(4)})
    assert not geometry.rays_blocked(ray)[0]
