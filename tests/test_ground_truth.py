"""Where render()'s depth, labels and instance ids come from (generator/geometry/pixel_truth.py,
docs/rendering.md): by default one ray per pixel centre into the scene's triangles, so they
do not depend on the renderer, its device, samples or seed; ``ground_truth="renderer"`` reads
Cycles' own passes (the paper's way), which agree up to float round-off."""

import math

import numpy as np
import pytest

from generator import Simulator
import scenes

W, H = 64, 48


@pytest.fixture(scope="module")
def yard(tmp_path_factory):
    """Ground, a wall in front of a crate, a pole, and a truck driving +x at 1 m per frame."""
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (100, 100), (0, 0, 0))
    scenes.add_box("Wall", (3, 0.2, 3), (-4, -5, 1.5))
    scenes.add_box("Crate", (1, 1, 1), (-3.0, -2, 0.5))  # its left edge behind the wall
    scenes.add_cylinder("Pole", 0.15, 4, (3, -3, 2))
    truck = scenes.add_box("Truck", (3, 2, 1), (0, 0, 1.0))
    truck.keyframe_insert("location", frame=1)
    truck.location.x = 10.0
    truck.keyframe_insert("location", frame=11)
    scenes.make_linear(truck)
    scenes.add_sun()
    scenes.add_camera((0, -15, 3), (math.radians(80), 0, 0))
    return scenes.save(tmp_path_factory.mktemp("gt") / "yard.blend")


def _truth(out):
    return out.depth.copy(), out.seg.copy(), out.instance.copy()


def test_ground_truth_is_the_pixel_centre_ray_cast_whatever_the_render(yard):
    sim = Simulator(yard, segmentation_sensitivity=0.0, render_preset="preview")
    sim.set_frame(1)
    first = sim.render()
    geo = sim.render_geometry(normals=False)
    assert np.array_equal(first.depth, geo.depth) and np.array_equal(first.seg, geo.seg)
    assert np.array_equal(first.instance, geo.instance)  # no instancing here: pass index = object id
    assert {sim.labels[i] for i in np.unique(first.seg[first.seg >= 0])} == {"Ground", "Wall", "Pole", "Truck", "Crate"}
    # another render of the same view with other samples, bounces, seed and threads: new colours, same truth
    sim.configure_render(samples=1, bounces=0, denoise=False, threads=1)
    sim.scene.cycles.seed = 7
    second = sim.render()
    assert not np.allclose(second.rgb_linear, first.rgb_linear)
    for a, b in zip(_truth(first), _truth(second)):
        assert np.array_equal(a, b)


def test_renderer_passes_agree_with_the_ray_cast(yard):
    sim = Simulator(yard, segmentation_sensitivity=0.0, render_preset="preview", ground_truth="renderer")
    sim.set_frame(3)
    cyc = sim.render()
    sim.ground_truth = "geometry"
    ours = sim.render()
    finite = np.isfinite(cyc.depth)
    assert np.array_equal(finite, np.isfinite(ours.depth)) and finite.mean() > 0.5
    rel = np.abs(ours.depth[finite] - cyc.depth[finite]) / cyc.depth[finite]
    assert np.median(rel) < 1e-4 and rel.max() < 5e-4  # float32 round-off; Cycles drifts at grazing angles (the ground)
    pad = np.pad(cyc.instance, 1, mode="edge")
    neigh = np.stack([pad[1 + di: 1 + di + H, 1 + dj: 1 + dj + W] for di in (-1, 0, 1) for dj in (-1, 0, 1)])
    interior = np.all(neigh == cyc.instance, axis=0)
    assert interior.mean() > 0.6
    assert np.array_equal(ours.instance[interior], cyc.instance[interior])
    assert np.array_equal(ours.seg[interior], cyc.seg[interior])
    before = sim.ground_truth
    with pytest.raises(ValueError, match="ground_truth must be one of"):
        sim.ground_truth = "both"  # refused where it is set, not at the next render
    assert sim.ground_truth == before
    with pytest.raises(ValueError, match="ground_truth must be one of"):
        Simulator(yard, ground_truth="cycles")


def test_depth_and_normals_are_exact_float64_hits(yard):
    """Depth is the planar distance of each pixel-centre ray (float64) to the triangle hit,
    rounded once to float32; normals are that triangle's. Embree's own float32 distance is
    off by up to ~100 float32 units in the last place here, and its arithmetic differs
    between CPU models (docs/guarantees.md), so this also pins the bytes across machines."""
    from exact_geometry import first_hits, scene_triangles
    from generator.geometry.camera import pixel_rays

    sim = Simulator(yard, segmentation_sensitivity=0.0)
    sim.set_frame(4)  # the truck has moved: its triangles come from the dynamic structure
    out = sim.render_geometry()
    pose = sim.get_world_from_camera()
    dirs = (pixel_rays(sim.K, W, H) @ pose[:3, :3].T).reshape(-1, 3)
    origins = pose[:3, 3] + sim.clip_start * dirs
    triangles = scene_triangles(sim.scene_parts()).astype(np.float32).astype(np.float64)  # as the structures hold them
    t, n = first_hits(origins, dirs, triangles)
    expected = (t + sim.clip_start).reshape(H, W)
    hit = np.isfinite(expected) & np.isfinite(out.depth)
    assert hit.mean() > 0.5 and np.array_equal(np.isfinite(expected), np.isfinite(out.depth))
    ulps = np.abs(out.depth[hit] - expected[hit]) / np.spacing(out.depth[hit])
    assert ulps.max() <= 1.0, f"depth off the float64 hit by up to {ulps.max():.1f} float32 ulps"
    assert (ulps <= 0.5 + 1e-6).mean() > 0.999  # correctly rounded but at float64 ties
    # normals: the triangle's, in the camera frame, facing the camera
    n_cam = (n @ pose[:3, :3]).reshape(H, W, 3)
    n_cam *= -np.sign(np.sum(n_cam * pixel_rays(sim.K, W, H), axis=-1, keepdims=True))
    assert np.abs(out.normal[hit] - n_cam[hit]).max() < 1e-6


def test_the_kept_answer_follows_pose_and_motion_and_is_not_shared(yard):
    sim = Simulator(yard, segmentation_sensitivity=0.0)
    sim.set_frame(1)
    truck = sim.object_names.index("Truck")
    at_1 = sim.render_geometry()
    on_truck = at_1.instance == truck
    assert on_truck.sum() > 20
    at_1.depth[:] = 0.0  # changing a returned array changes nothing kept
    assert np.array_equal(sim.render_geometry().depth[on_truck], sim.render_geometry(normals=False).depth[on_truck])
    assert np.all(sim.render_geometry().depth > 0)
    sim.set_frame(8)  # the truck drove 7 m to +x: its old pixels see the ground (or the pole) now
    at_8 = sim.render_geometry(normals=False)
    assert (at_8.instance[on_truck] != truck).mean() > 0.5
    assert np.array_equal(at_8.depth, sim.render_geometry().depth)
    pose = sim.get_world_from_camera()
    pose[0, 3] += 1.0
    sim.set_world_from_camera(pose, check_collisions=False)
    moved = sim.render_geometry(normals=False)
    assert not np.array_equal(moved.instance, at_8.instance)


def test_filtered_objects_hide_what_is_behind_them_unlabelled(yard):
    plain = Simulator(yard, segmentation_sensitivity=0.0, render_preset="preview")
    plain.set_frame(1)
    ref = plain.render_geometry(normals=False)
    wall_px, truck_px = [ref.instance == plain.object_names.index(n) for n in ("Wall", "Truck")]
    assert wall_px.sum() > 20 and truck_px.sum() > 20
    sim = Simulator(yard, segmentation_sensitivity=0.0, render_preset="preview", filter_object_names=["Wall", "Truck"])
    sim.set_frame(1)
    for out in (sim.render(), sim.render_geometry()):
        for px in (wall_px, truck_px):  # still surfaces at their own depth, unlabelled
            assert np.all(out.seg[px] == -1) and np.all(out.instance[px] == -1)
            assert np.allclose(out.depth[px], ref.depth[px], rtol=1e-6)
    assert "Wall" not in sim.labels and "Truck" not in sim.labels
    # the filtered truck moves with the animation: at frame 8 its old pixels see the ground again
    sim.set_frame(8)
    out = sim.render()
    assert (out.seg[truck_px] == sim.labels.index("Ground")).mean() > 0.3
    sim.ground_truth = "renderer"  # Cycles' passes see the same
    cyc = sim.render()
    assert (cyc.seg[truck_px] == out.seg[truck_px]).mean() > 0.9


def test_instanced_copies_get_their_own_ids(tmp_path):
    """Blender's Object Index pass gives every copy of an instanced collection the source
    object's pass index; the rays tell the copies apart, as ``object_names`` and the points do."""
    import bpy

    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (100, 100), (0, 0, 0))
    coll = bpy.data.collections.new("CrateSet")
    crate = bpy.data.objects.new("Crate", bpy.data.meshes.new("Crate"))
    crate.data.from_pydata([(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (0, 1)], [],
                           [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    coll.objects.link(crate)
    for k, x in enumerate((-1.5, 1.5)):
        empty = bpy.data.objects.new(f"CrateCopy.{k:03d}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = coll
        empty.location = (x, 6, 0)
        bpy.context.scene.collection.objects.link(empty)
    scenes.look_along_y((0, 0, 1.5))
    sim = Simulator(scenes.save(tmp_path / "copies.blend"), segmentation_sensitivity=0.0, render_preset="preview",
                    points_density=50)
    copies = [i for i, n in enumerate(sim.object_names) if n.endswith("Crate#0") or "/Crate#" in n]
    assert len(copies) == 2
    out = sim.render()
    seen = [int((out.instance == i).sum()) for i in copies]
    assert min(seen) > 20  # both copies, each under its own id
    assert np.array_equal(out.instance, sim.render_geometry(normals=False).instance)
    crate_label = sim.labels.index("Crate")
    assert np.array_equal(out.seg == crate_label, np.isin(out.instance, copies))
    # the points on each copy carry that copy's id, as the pixels showing it do
    assert set(np.unique(sim.point_instances)) >= set(copies)
    sim.ground_truth = "renderer"  # the paper's passes: one pass index for both copies
    cyc = sim.render()
    on_copies = np.isin(out.instance, copies)
    assert len(np.unique(cyc.instance[on_copies])) == 1 and cyc.instance[on_copies][0] in copies


def test_a_ray_in_a_triangles_plane_keeps_a_depth_past_the_near_plane():
    """A pixel ray lying in the plane of the triangle it hits (camera centre on the plane):
    the float64 plane distance is meaningless there (it came out negative, up to -1e4 m,
    in 3% of such rays), so the depth must fall back to Embree's hit, never below clip_start."""
    from generator.geometry.parts import MeshPart
    from generator.geometry.raycam import RayCamera
    from generator.geometry.raycast import SceneGeometry

    rng = np.random.default_rng(0)
    clip = 0.1
    cam = RayCamera(np.array([[100.0, 0, 1.5], [0, 100.0, 1.5], [0, 0, 1]]), 3, 3, clip, 1000.0)
    depths = []
    for _ in range(1500):
        tri = rng.uniform(-30, 30, (3, 3)).astype(np.float32).astype(np.float64)
        a, b, c = tri
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        z = rng.normal(size=3)
        z -= (z @ n) * n
        z /= np.linalg.norm(z)  # the optical axis in the triangle's plane
        x = np.cross(n, z)
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2] = x, np.cross(z, x), z
        pose[:3, 3] = a + 0.3 * (b - a) + 0.3 * (c - a) - rng.uniform(2, 40) * z
        hits = cam.cast(SceneGeometry([MeshPart("t", "x", tri, np.array([[0, 1, 2]]))]), pose, normals=False)
        depths.append(hits.depth[1, 1])
    depths = np.array(depths)
    hit = np.isfinite(depths)
    assert hit.mean() > 0.1
    assert depths[hit].min() >= clip, f"{(depths[hit] < clip).sum()} depths below the near plane"


def _wall(origin, angle_deg, length=30.0, height=10.0, cells=(30, 10)):
    """A vertical wall of 2 x cells triangles (float32 vertices) from ``origin`` along the
    horizontal direction ``angle_deg``: (vertices, faces, along, its normal)."""
    a = math.radians(angle_deg)
    along, up = np.array([math.cos(a), math.sin(a), 0.0]), np.array([0.0, 0.0, 1.0])
    nu, nv = cells
    uu, vv = np.meshgrid(np.linspace(0, length, nu + 1), np.linspace(0, height, nv + 1), indexing="ij")
    verts = (uu.reshape(-1, 1) * along + vv.reshape(-1, 1) * up + origin).astype(np.float32).astype(np.float64)
    k = (np.arange(nu)[:, None] * (nv + 1) + np.arange(nv)[None, :]).reshape(-1)
    faces = np.concatenate([np.stack([k, k + nv + 1, k + 1], 1), np.stack([k + 1, k + nv + 1, k + nv + 2], 1)])
    return verts, faces, along, np.cross(along, up)


def test_depth_along_a_wall_seen_from_beside_its_plane_is_the_float64_hit():
    """A camera 0.1 mm-10 cm from the plane of a tiled wall 200 m from the origin, looking
    along it: the float32 ray (Embree's) meets the wall millimetres to centimetres from where
    the float64 one does, often on another tile. The depth must still be the float64 ray's
    first hit (the tile it really meets), not Embree's distance or the float32 ray's (which
    were up to 4 mm and 5,600 float32 ulps off here, and CPU-dependent)."""
    from exact_geometry import first_hits
    from generator.geometry.camera import pixel_rays
    from generator.geometry.parts import MeshPart
    from generator.geometry.raycam import RayCamera
    from generator.geometry.raycast import SceneGeometry

    rng = np.random.default_rng(1)
    start = np.array([183.0, 161.0, 20.0])
    w, h, clip = 64, 48, 0.1
    K = np.array([[40.0, 0, w / 2], [0, 40.0, h / 2], [0, 0, 1]])
    cam = RayCamera(K, w, h, clip, 1000.0)
    compared, worst = 0, 0.0
    for angle in (17.0, -63.0):
        verts, faces, along, normal = _wall(start, angle)
        geometry = SceneGeometry([MeshPart("wall", "wall", verts, faces)])
        for _ in range(20):
            yaw = math.radians(rng.uniform(2, 25))  # the optical axis turned toward the wall
            centre = (start + rng.uniform(0.5, 8) * along + [0, 0, rng.uniform(1, 9)]
                      + (clip * math.sin(yaw) + 10 ** rng.uniform(-4, -1)) * normal)
            z = math.cos(yaw) * along - math.sin(yaw) * normal
            x = np.cross(z, [0, 0, 1.0])
            x /= np.linalg.norm(x)
            pose = np.eye(4)
            pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, np.cross(z, x), z, centre
            depth = cam.cast(geometry, pose, normals=False).depth
            dirs = (pixel_rays(K, w, h) @ pose[:3, :3].T).reshape(-1, 3)
            expected = (first_hits(centre + clip * dirs, dirs, verts[faces])[0] + clip).reshape(h, w)
            # the two rays may disagree on whether they hit only along the wall's border
            one = (np.isfinite(expected) != np.isfinite(depth)).reshape(-1)
            p = centre + np.fmin(expected, depth).reshape(-1)[one, None] * dirs[one] - start
            u, v = p @ along, p[:, 2]
            assert np.all(np.minimum(np.minimum(u, 30 - u), np.minimum(v, 10 - v)) < 1e-3)
            hit = np.isfinite(depth) & np.isfinite(expected)
            ulps = np.abs(depth[hit] - expected[hit]) / np.spacing(depth[hit])
            compared, worst = compared + hit.sum(), max(worst, ulps.max(initial=0.0))
    assert compared > 20_000
    assert worst <= 1.0, f"depth off the float64 hit by up to {worst:.1f} float32 ulps"
