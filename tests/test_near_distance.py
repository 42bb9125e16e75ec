"""Exact float64 distances to the triangles near a point (generator/geometry/near_distance.py),
against an independent numpy twin (tests/exact_geometry.py), needle triangles included."""

import numpy as np
import pytest
from exact_geometry import exact_distance

from generator.geometry.near_distance import near_distances


def test_exact_distances_on_needles_degenerate_triangles_and_far_points():
    rng = np.random.default_rng(0)
    tri = rng.normal(size=(300, 3, 3))
    tri[:50, 2] = tri[:50, 0] + (tri[:50, 1] - tri[:50, 0]) * 0.5 + 1e-3 * rng.normal(size=(50, 3))  # needles
    tri[50:55, 2] = tri[50:55, 0]  # no area: a segment
    points = rng.normal(size=(1000, 3)) * 1.5
    reference = np.array([exact_distance(p, tri) for p in points])
    got = near_distances(points, tri, 10.0)
    np.testing.assert_allclose(got, reference, rtol=0, atol=1e-12)
    # with a small radius: exact wherever some triangle is that near, never a false "near"
    small = near_distances(points, tri, 0.05)
    near = reference <= 0.05
    assert near.sum() > 20
    np.testing.assert_allclose(small[near], reference[near], rtol=0, atol=1e-12)
    assert (small[~near] > 0.05).all()
    # the same bits however the points are ordered (each point is its own computation)
    order = rng.permutation(len(points))
    assert np.array_equal(near_distances(points[order], tri, 0.05), small[order])


def test_triangles_with_no_area_are_their_edges():
    """Collinear corners (c before a, between a and b, beyond b, on a or b): the cross product is
    round-off, not 0, and the point's region is decided by noise; the answer is the segment's."""
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(20, 3)), rng.normal(size=(20, 3))
    for f in (-0.5, 0.0, 0.3, 1.0, 1.7):
        tri = np.stack([a, b, a + f * (b - a)], axis=1)
        points = rng.normal(size=(300, 3))
        reference = np.array([exact_distance(p, tri) for p in points])
        np.testing.assert_allclose(near_distances(points, tri, 10.0), reference, rtol=0, atol=1e-12)


@pytest.mark.parametrize("sine", [1e-10, 1e-8, 1e-6, 1e-4, 1e-2])
@pytest.mark.parametrize("tip", [0, 1, 2])
def test_needles_whatever_corner_is_the_tip(sine, tip):
    """A 10 m needle of tip angle ~``sine`` in the plane z = 0, turned and moved by a rigid
    motion: a point above its face is |z| from it, one beyond its tip is at the tip's distance.
    (Ericson's region tests were metres off at 1e-8 with the tip first, millimetres at 1e-6.)"""
    rng = np.random.default_rng(tip)
    length, width = 10.0, 10.0 * sine
    corners = np.array([[0.0, 0.0, 0.0], [length, 0.0, 0.0], [length, width, 0.0]])
    x = rng.uniform(0.5, length - 0.5, 200)
    inside = np.stack([x, x * width / length * rng.uniform(0, 1, 200), rng.uniform(-0.1, 0.1, 200)], axis=1)
    beyond = np.stack([-rng.uniform(0.01, 0.1, 200), rng.uniform(-0.05, 0.05, 200), rng.uniform(-0.1, 0.1, 200)], axis=1)
    expected = np.r_[np.abs(inside[:, 2]), np.linalg.norm(beyond, axis=1)]
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    move = lambda v: v @ q.T + np.array([40.0, -25.0, 3.0])  # noqa: E731
    tri = move(np.roll(corners, tip, axis=0))[None]
    got = near_distances(move(np.r_[inside, beyond]), tri, 0.5)
    # the rigid motion's own rounding; and a needle's width where its plane is not used (sine <= 1e-8)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 + (width if sine <= 1e-8 else 0.0))


def test_a_point_on_a_scaffold_tube_is_at_distance_zero():
    """Points lying on a 14.7 m x 1.5 cm face (a scaffold tube's), 10 m from the origin, among
    the tube's other faces: their distance is their float64 round-off."""
    a, b = np.array([10.0, 3.0, 1.0]), np.array([10.0, 3.0, 15.7])
    turn = [np.array([np.cos(k * np.pi / 4), np.sin(k * np.pi / 4), 0.0]) * 0.024 for k in range(9)]
    faces = [[a + turn[k], b + turn[k], a + turn[k + 1]] for k in range(8)]
    faces += [[b + turn[k], b + turn[k + 1], a + turn[k + 1]] for k in range(8)]
    tri = np.array(faces)
    w = np.random.default_rng(1).dirichlet([1, 1, 1], 2000)
    points = np.einsum("nk,kj->nj", w, tri[0])
    assert near_distances(points, tri, 0.1).max() < 1e-12
