"""The ground's relief (generator/scene/relief.py, generator/scene/ground_layout.py): digs cut
into one watertight ground, their depth where a ray meets them, ruts, the terrain beyond the
fence, spoil heaps beside the pits, nothing placed on a dig in any stage, and the working
level and contact-face rule of the surface points on such a ground."""

import json

import numpy as np
import pytest

from generator.geometry.parts import MeshPart
from generator.geometry.sampling import contact_faces, ground_height
from generator.scene.assets import overlaps
from generator.scene.catalogue.ground import GROUND_MARGIN, RUT_DEPTH_M
from generator.scene.relief import RAMP_RUN, TERRAIN_FLAT_M
from generator.scene.site import plan_site, site_ground, site_params

@pytest.fixture(scope="module")
def plans(medium_plans):
    """Medium seeds 0-11 (conftest.py)."""
    return medium_plans


def _triangles(mesh) -> np.ndarray:
    quads = np.asarray(mesh.quads, dtype=np.int64).reshape(-1, 4)
    tris = np.concatenate([np.asarray(mesh.tris, dtype=np.int64).reshape(-1, 3), quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return tris


def _welded(mesh) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, triangles) with vertices at bit-identical positions merged."""
    v = np.asarray(mesh.vertices, dtype=np.float64) + 0.0  # -0.0 and 0.0: one position
    unique, index = np.unique(v, axis=0, return_inverse=True)
    return unique, index.ravel()[_triangles(mesh)]


def _with_relief(plans, kind: str):
    return next(p for p in plans.values() if any(d.kind == kind for d in p.relief.digs))


def test_the_ground_is_watertight_and_consistently_turned_around_its_relief(plans):
    """Welding vertices at identical positions, every edge of the ground is shared by exactly
    two triangles running it in opposite directions (no hole, crack or T-junction, one
    orientation), but the edges of the ground's outer square."""
    pit, trench = _with_relief(plans, "pit"), _with_relief(plans, "trench")
    rutted = next(p for p in plans.values() if p.ground.rut_depth > 0)
    for plan in {p.seed: p for p in (pit, trench, rutted)}.values():
        v, t = _welded(site_ground(plan).mesh)
        edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
        key = np.sort(edges, axis=1)
        _, inverse, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        outer = plan.params.size / 2 + GROUND_MARGIN
        on_rim = np.all(np.isclose(np.abs(v[key][:, :, :2]), outer).any(axis=2), axis=1)  # both ends on the outer square
        per_edge = count[inverse.ravel()]
        assert np.all(per_edge[~on_rim] == 2) and np.all(per_edge[on_rim] == 1)
        directed = {tuple(e) for e in edges}
        assert len(directed) == len(edges)  # no edge run twice the same way: neighbours agree on orientation
        up = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])[:, 2]
        assert np.all(up >= 0)  # turned to the air (a ramp's side walls are vertical)


def test_a_ray_down_meets_the_pit_floor_the_ramp_and_the_trench_at_their_depths(plans):
    from generator.geometry.o3d import import_open3d

    o3d = import_open3d()

    for kind in ("pit", "trench"):
        plan = _with_relief(plans, kind)
        dig = next(d for d in plan.relief.digs if d.kind == kind)
        mesh = site_ground(plan).mesh
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(_triangles(mesh).astype(np.uint32)))
        local = [(0.0, 0.0)]  # the floor's centre
        if dig.ramp:
            local.append((dig.floor[0] / 2 + RAMP_RUN * dig.depth / 2, 0.0))  # half way up the ramp
        outside = dig.outline().max(axis=0) + 0.3
        xy = np.vstack([dig.to_world(np.array(local)), outside[None]])
        rays = np.column_stack([xy, np.full(len(xy), 10.0), np.zeros((len(xy), 2)), -np.ones(len(xy))]).astype(np.float32)
        hit_z = 10.0 - scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        expected = [-dig.depth] + ([-dig.depth / 2] if dig.ramp else []) + [0.0]
        np.testing.assert_allclose(hit_z, expected, atol=1e-4)
        assert 1.0 <= dig.depth <= 3.0


def test_pit_sides_are_battered_at_45_to_60_degrees_and_trench_sides_nearly_vertical(plans):
    for plan in plans.values():
        for dig in plan.relief.digs:
            v, f = dig.faces()
            n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            tilt = np.degrees(np.arccos(np.clip(n[:, 2], -1, 1)))
            sides = (tilt > 1) & (tilt < 89)
            steep = tilt[sides].max()
            if dig.kind == "pit":
                assert 44.9 < steep < 60.1 and np.isclose(tilt[sides].min(), np.degrees(np.arctan(1 / RAMP_RUN)))
            else:
                assert steep > 84


def test_ruts_are_sunk_on_unpaved_roads_only(plans):
    for plan in plans.values():
        z = site_ground(plan).mesh.vertices[:, 2]
        inside = np.abs(site_ground(plan).mesh.vertices[:, :2]).max(axis=1) < plan.params.size / 2
        levels = set(np.unique(z[inside & (z > -0.5)]))
        expected = {0.0, -RUT_DEPTH_M} if plan.ground.road not in ("asphalt", "concrete") else {0.0}
        assert levels == expected, (plan.seed, plan.ground.road, levels)


def test_the_terrain_beyond_the_fence_is_level_at_the_fence_and_rises_gently(plans):
    for plan in list(plans.values())[:10]:
        mesh = site_ground(plan).mesh
        v = mesh.vertices
        half = plan.params.size / 2
        beyond = np.abs(v[:, :2]).max(axis=1) - half
        assert np.all(v[beyond <= 1e-9, 2] <= 0.0)  # level (or ruts, digs) up to the fence line
        first = (beyond > 0) & (beyond < 2.01)  # the first row out, 2 m from the fence
        assert first.sum() > 50 and np.abs(v[first, 2]).max() < 0.5
        assert len(mesh.quads) == 0  # the ground is made of triangles only
        t = np.asarray(mesh.tris)
        grass = np.array([mesh.materials[i] == "grass" for i in mesh.face_material])
        n = np.cross(v[t[grass, 1]] - v[t[grass, 0]], v[t[grass, 2]] - v[t[grass, 0]])
        slope = np.linalg.norm(n[:, :2], axis=1) / n[:, 2]
        assert slope.max() < 0.45 and np.median(slope) < 0.2  # gentle
        edge = v[beyond > GROUND_MARGIN - 1e-6, 2]
        rise = plan.relief.terrain.rise
        amp = sum(w[3] for w in plan.relief.terrain.waves)
        assert np.all(np.abs(edge - rise) <= amp + 1e-9)
        if plan.context.terrain > 0:  # the context scales the relief; an urban site's surroundings are level
            assert edge.std() > 0.05 * plan.context.terrain
        else:
            assert np.all(v[:, 2][beyond > 0] == 0.0)
        assert TERRAIN_FLAT_M < GROUND_MARGIN


def test_pits_and_trenches_over_seeds_with_a_spoil_heap_beside_each_pit(plans):
    pits = [p for p in plans.values() if any(d.kind == "pit" for d in p.relief.digs)]
    trenches = [p for p in plans.values() if any(d.kind == "trench" for d in p.relief.digs)]
    assert len(pits) >= 0.5 * len(plans) and len(trenches) >= 0.25 * len(plans), (len(pits), len(trenches))
    for plan in plans.values():
        digs = [d.footprint() for d in plan.relief.digs]
        for placed in plan.placed:  # nothing is placed on a dig, nor the dig on the road
            assert not any(overlaps(placed.footprint, fp) for fp in digs), (plan.seed, placed.asset.kind)
        heaps = [p for p in plan.placed if p.asset.kind == "SpoilHeap"]
        assert len(heaps) <= sum(d.kind == "pit" for d in plan.relief.digs)
        for heap in heaps:
            assert heap.asset.parts[0].label == "Ground"
            pit = next(d for d in plan.relief.digs if d.kind == "pit")
            gap = np.linalg.norm(np.subtract(heap.footprint.center, pit.footprint().center))
            assert gap < (max(pit.footprint().size) + max(heap.footprint.size)) / 2 + 8.0
    assert sum(p.asset.kind == "SpoilHeap" for plan in pits for p in plan.placed) >= 0.5 * len(pits)


def test_the_relief_is_the_same_in_every_stage_and_deliveries_avoid_the_digs(medium_plans):
    params = site_params("medium", frames=20)
    seed = next(s for s, plan in medium_plans.items() if plan.relief.digs)
    stages = [plan_site(seed, params, stage=k, stages=3) for k in range(3)]
    assert all(s.relief.summary() == stages[0].relief.summary() for s in stages)
    for s in stages:
        digs = [d.footprint() for d in s.relief.digs]
        assert not any(overlaps(p.footprint, fp) for p in s.placed for fp in digs)
    assert json.loads(json.dumps(stages[0].summary()))["relief"]["digs"][0]["depth"] == stages[0].relief.digs[0].depth


def test_the_working_level_and_a_spoil_heap_base_on_a_ground_with_relief(plans):
    """The working level is where most of the ground's level area lies (z = 0, not a pit floor
    or a rut); a heap's base resting on it carries no points, the open ground's faces all do;
    a ground with no level face has no working level."""
    plan = next(p for p in _pits_with_heaps(plans))
    ground = site_ground(plan).mesh
    parts = [MeshPart("ground", "Ground", ground.vertices, _triangles(ground))]
    heap = next(p for p in plan.placed if p.asset.kind == "SpoilHeap")
    hm = heap.asset.parts[0].mesh
    from generator.geometry.parts import closed_and_orientation

    closed, outward = closed_and_orientation(hm.vertices, _triangles(hm))
    parts.append(MeshPart("heap", "Ground", hm.vertices, _triangles(hm), closed=closed, outward=outward))
    assert closed and ground_height(parts) == 0.0
    assert not contact_faces(parts[0], 0.0).any()
    base = contact_faces(parts[1], 0.0)
    assert base.any() and np.all(np.abs(hm.vertices[_triangles(hm)[base]][:, :, 2]) < 1e-9)
    tilted = np.array([[0, 0, 0], [10, 0, 5], [0, 10, 0]], dtype=float)
    assert ground_height([MeshPart("slope", "Ground", tilted, np.array([[0, 1, 2]]))]) is None


def _pits_with_heaps(plans):
    return [p for p in plans.values() if any(x.asset.kind == "SpoilHeap" for x in p.placed)]
