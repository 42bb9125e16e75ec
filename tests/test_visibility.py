"""Visibility rule: frustum, depth limits, occlusion, grazing angles, back-face shortcut."""

import math

import numpy as np
import pytest

import scenes
from generator import Simulator
from generator.geometry.camera import project as cam_project
from generator.geometry.parts import MeshPart
from generator.geometry.raycast import OCCLUSION_TOL_ABS, OCCLUSION_TOL_REL, SceneGeometry
from generator.geometry.surface_points import SurfacePoints
from generator.geometry.visibility import ViewLimits, VisibilityStats, visible_points


@pytest.fixture(scope="module")
def walls(walls_blend):
    return walls_blend


def _visibility_of(sim, points):
    """Visibility of extra probe points, evaluated with the simulator's own rule on its
    (static) scene's triangles."""
    assert not sim.dynamic_objects
    return visible_points(
        SceneGeometry(sim.scene_parts()), np.asarray(points, float), None, None, sim.get_world_from_camera(), sim.K,
        sim.width, sim.height, ViewLimits(sim.clip_start, min(sim.clip_end, sim.max_pcl_depth)),
    )


def test_front_behind_outside_and_depth_limit(walls):
    sim = Simulator(walls, points_density=20)
    # the wall's front face is at y = 4.9; camera at (0, 0, 1.5) looking along +Y
    probes = [
        (0.0, 4.9, 1.5),    # on the wall's front face: visible
        (0.0, 5.1, 1.5),    # on the wall's back face: hidden by the wall
        (0.0, 7.0, 1.5),    # in the air behind the wall: hidden
        (0.0, 3.0, 1.5),    # in the air in front of the wall: visible
        (0.0, -1.0, 1.5),   # behind the camera: not visible
        (30.0, 3.0, 1.5),   # far outside the horizontal field of view
    ]
    vis = _visibility_of(sim, probes)
    assert vis.tolist() == [True, False, False, True, False, False]

    near = Simulator(walls, points_density=20, max_pcl_depth=4.0)
    vis = _visibility_of(near, [(0.0, 3.0, 1.5), (0.0, 4.5, 1.5)])
    assert vis.tolist() == [True, False]  # planar depth 3 <= 4 < 4.5


def test_all_sampled_points_follow_the_rule(walls):
    sim = Simulator(walls, points_density=40)
    pts, labels, vis = sim.compute_point_cloud()
    wall = sim.labels.index("Wall")
    crate = sim.labels.index("Crate")
    uv, z = sim.project(pts)
    in_image = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < sim.width) & (uv[:, 1] >= 0) & (uv[:, 1] < sim.height)
    assert not np.any(vis & ~in_image)
    # wall points on its front face (y = 4.9) in the image are visible; its back face never
    front = (labels == wall) & (np.abs(pts[:, 1] - 4.9) < 1e-6) & in_image
    back = (labels == wall) & (np.abs(pts[:, 1] - 5.1) < 1e-6)
    assert front.sum() > 50 and vis[front].all()
    assert not vis[back].any()
    # both crates stand behind/beside the wall at y = 8: their faces pointing at the camera
    # are visible where not hidden by the wall
    assert vis[labels == crate].any()
    assert 0 < sim.coverage < 1
    assert sim.coverage == pytest.approx(vis.mean())


def test_grazing_angle_points_are_visible(tmp_path):
    scenes.new_scene(64, 48)
    scenes.add_plane("Ground", (200, 200), (0, 0, 0))
    cam = scenes.add_camera((0, 0, 0.2), (math.radians(89.0), 0, 0), lens=20)  # 1 degree below the horizon
    path = scenes.save(tmp_path / "grazing.blend")
    sim = Simulator(path, points_density=2.0)
    pts, _, vis = sim.compute_point_cloud()
    uv, z = sim.project(pts)
    in_image = (z > 0.1) & (uv[:, 0] >= 0) & (uv[:, 0] < 64) & (uv[:, 1] >= 0) & (uv[:, 1] < 48)
    far_grazing = in_image & (np.linalg.norm(pts - [0, 0, 0.2], axis=1) > 5)  # seen at < 2.3 degrees
    assert far_grazing.sum() > 100
    assert vis[far_grazing].all(), f"{(~vis[far_grazing]).sum()} grazing points wrongly hidden"
    assert vis[in_image].all()


def test_backface_rule_agrees_with_pure_ray_casting(walls):
    """Rule 3 (back faces of solids are hidden, no ray cast) agrees with pure ray casting,
    except at silhouettes where the ray enters the solid within the occlusion tolerance."""
    sim = Simulator(walls, points_density=30)
    rng = np.random.default_rng(0)
    assert not sim.dynamic_objects  # static parts: the sample's local frame is the world
    sample = sim.surface_sample()
    world, normals, part = sim.point_positions, sample["local_normals"], sample["part"]
    geometry = SceneGeometry(sim.scene_parts())
    checked = 0
    for _ in range(8):
        pose = sim.get_world_from_camera()
        pose[:3, 3] = [rng.uniform(-8, 8), rng.uniform(-4, 14), rng.uniform(0.5, 6)]
        yaw = rng.uniform(0, 2 * math.pi)
        c, s = math.cos(yaw), math.sin(yaw)
        pose[:3, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ pose[:3, :3]
        args = (geometry, world)
        tail = (pose, sim.K, sim.width, sim.height, ViewLimits(sim.clip_start, sim.clip_end))
        fast = visible_points(*args, normals, part, *tail)
        slow = visible_points(*args, None, None, *tail)
        checked += slow.sum()
        differ = np.flatnonzero(fast != slow)
        assert not np.any(fast[differ])  # the rule only ever hides
        centre = pose[:3, 3]
        d = np.linalg.norm(world[differ] - centre, axis=1)
        t, _ = geometry.cast(np.repeat(centre[None], len(differ), 0), (world[differ] - centre) / d[:, None])
        assert np.all(d - t < OCCLUSION_TOL_ABS + OCCLUSION_TOL_REL * d + 1e-6)
        assert len(differ) <= 1e-3 * max(slow.sum(), 1) + 2
    assert checked > 1000


def test_dynamic_occluder_hides_points():
    ground = MeshPart("Ground", "Ground", np.array([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0.0]]),
                      np.array([[0, 1, 2], [0, 2, 3]]))
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    box = MeshPart("Box", "Box", v, f, dynamic=True, matrix=np.eye(4))
    geo = SceneGeometry([ground, box])
    pose = np.array([[1, 0, 0, 0], [0, 0, 1, -10], [0, -1, 0, 3], [0, 0, 0, 1.0]])  # looking along +Y
    K = np.array([[50, 0, 32], [0, 50, 24], [0, 0, 1.0]])
    probe = np.array([[0.0, 5.0, 3.0]])  # in the air behind where the box will be
    moved = np.eye(4)
    moved[:3, 3] = [0, 0, 3]
    assert visible_points(geo, probe, None, None, pose, K, 64, 48)[0]
    geo.set_matrices({1: moved})
    assert not visible_points(geo, probe, None, None, pose, K, 64, 48)[0]


def test_point_groups_equal_one_ray_per_point_on_exact_boundaries():
    """Points exactly on the image borders, on the depth limits and on a solid's face whose
    plane passes through the camera: the point groups (decisions per group only with a
    margin) give the same bits as testing every point, and the boundaries fall where the
    rules put them (u = 0 in, u = W z out, z = far in, z = near out; n . (p - c) = 0 is not
    rule 3)."""
    ground = MeshPart("Ground", "Ground", np.array([[-500, -500, -20], [500, -500, -20], [500, 500, -20],
                                                   [-500, 500, -20.0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    v = np.array([[x, y, z] for x in (0, 2) for y in (5, 7) for z in (-1, 1)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    box = MeshPart("Box", "Box", v, f, closed=True)
    geo = SceneGeometry([ground, box])
    pose = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1.0]])  # at the origin, looking along +Y
    K = np.array([[50, 0, 32], [0, 50, 24], [0, 0, 1.0]])
    limits = ViewLimits(1.0, 40.0)
    rng = np.random.default_rng(3)
    j = np.repeat(np.arange(1, 7), 60).astype(float)  # depths 6.25 j m: every product below is exact
    zs = rng.uniform(-1, 1, len(j)) * j
    sets = {  # name: (points, expected visible; nothing stands between them and the camera)
        "left border": (np.c_[-4 * j, 6.25 * j, zs], True),      # u = 50 x + 32 y = 0
        "left outside": (np.c_[-4 * j - 1e-6, 6.25 * j, zs], False),
        "right border": (np.c_[4 * j, 6.25 * j, zs], False),     # u = 50 x + 32 y = 64 y = W z
        "far limit": (np.c_[rng.uniform(-5, -1, 200), np.full(200, 40.0), rng.uniform(-5, 5, 200)], True),
        "near limit": (np.c_[rng.uniform(-0.3, 0.3, 200), np.full(200, 1.0), rng.uniform(-0.3, 0.3, 200)], False),
    }
    points = np.concatenate([p for p, _ in sets.values()])
    normals = np.zeros_like(points)
    part = np.zeros(len(points), dtype=np.int32)
    # on the box: its face x = 0 (plane through the camera), its front y = 5 and back y = 7
    face = np.c_[np.zeros(300), rng.uniform(5, 7, 300), rng.uniform(-1, 1, 300)]
    front = np.c_[rng.uniform(0, 2, 300), np.full(300, 5.0), rng.uniform(-1, 1, 300)]
    back = np.c_[rng.uniform(0, 2, 300), np.full(300, 7.0), rng.uniform(-1, 1, 300)]
    points = np.concatenate([points, face, front, back])
    normals = np.concatenate([normals, np.tile([-1.0, 0, 0], (300, 1)), np.tile([0, -1.0, 0], (300, 1)),
                              np.tile([0, 1.0, 0], (300, 1))])
    part = np.concatenate([part, np.ones(900, dtype=np.int32)])
    stats = VisibilityStats()
    fast = visible_points(geo, points, normals, part, pose, K, 64, 48, limits, stats)
    ref = visible_points(geo, points, normals, part, pose, K, 64, 48, limits, ray_per_point=True)
    assert np.array_equal(fast, ref)
    start = 0
    for name, (p, expected) in sets.items():
        assert fast[start:start + len(p)].all() == expected and fast[start:start + len(p)].any() == expected, name
        start += len(p)
    on_face, on_front, on_back = np.split(np.arange(start, len(points)), 3)
    assert stats.culled_backfacing == 300 and not fast[on_back].any()
    assert fast[on_front].all()
    # the boundary sets and the face seen edge-on are tested point by point; the front and
    # back faces (wholly in view, facing one way) are settled per group
    assert len(points) - 600 <= stats.tested_one_by_one <= len(points) - 500
    # the face seen edge-on is decided by rays (not rule 3): the same answers as without normals
    edge_on = visible_points(geo, points[on_face], None, None, pose, K, 64, 48, limits)
    assert np.array_equal(fast[on_face], edge_on)
    # without normals (no rule 3) the groups give the ray-per-point answer too
    no_normals = visible_points(geo, points, None, part, pose, K, 64, 48, limits)
    assert np.array_equal(no_normals, visible_points(geo, points, None, part, pose, K, 64, 48, limits,
                                                     ray_per_point=True))
    assert np.array_equal(no_normals, fast)  # the box's back face is hidden by its front face anyway


def _spread_values(rng, n):
    """Values of every sign and magnitude from 1e-3 to 1e4 (round-off differences show)."""
    return rng.choice([-1.0, 1.0], n) * 10.0 ** rng.uniform(-3, 4, n) * rng.uniform(1, 2, n)


def test_kernel_arithmetic_rounds_as_the_rules():
    """The compiled per-point arithmetic (point_block_kernels) gives the same bits as numpy's
    evaluation of the rules' expressions (visibility_rules.in_view and occlusion_rays): no
    reordering, no fused multiply-add."""
    from generator.geometry.point_block_kernels import segment_keep_of, view_coords_of

    rng = np.random.default_rng(11)
    n = 200_000
    dx, dy, dz = (_spread_values(rng, n) for _ in range(3))
    rows = [_spread_values(rng, 3) for _ in range(3)]
    got = view_coords_of(dx, dy, dz, *rows)
    for k, a in enumerate(rows):  # in_view: dx * a[0] + dy * a[1] + dz * a[2], left to right
        assert np.array_equal(got[k].view(np.int64), (dx * a[0] + dy * a[1] + dz * a[2]).view(np.int64))
    dx[:3], dy[:3], dz[:3] = 0.0, [0.0, 1e-4, 2e-3], 0.0  # at the centre, inside and outside the tolerance
    dist = np.sqrt(dx * dx + dy * dy + dz * dz)
    with np.errstate(divide="ignore"):
        keep = np.maximum(1.0 - (OCCLUSION_TOL_ABS + OCCLUSION_TOL_REL * dist) / dist, 0.0)
    got = segment_keep_of(dx, dy, dz)
    assert got[0] == 0 and got[1] == 0 and got[2] > 0
    assert np.array_equal(got.view(np.int64), keep.view(np.int64))


def test_kernels_have_no_fused_multiply_add():
    """numba is not allowed to fuse a * b + c into one rounding (it would change the bits of
    the rules' tests, and make the ground truth's bits depend on the CPU): no FMA instruction
    in the compiled code of the visibility kernels (compute_point_cloud's and the
    observability mask's) and of the pixel ground truth's (exact_kernels)."""
    import re

    import numba

    from generator.geometry import exact_kernels, near_distance
    from generator.geometry import point_block_kernels as kernels
    from generator.geometry.observability import visible_from
    from generator.geometry.point_block_kernels import omni_rays
    from generator.lidar import kernels as lidar_kernels
    from generator.lidar import physics

    sim_points = np.random.default_rng(0).uniform(-5, 5, (500, 3))
    ground = MeshPart("Ground", "Ground", np.array([[-50, -50, -6], [50, -50, -6], [50, 50, -6], [-50, 50, -6.0]]),
                      np.array([[0, 1, 2], [0, 2, 3]]), closed=False)
    pose = np.array([[1, 0, 0, 0], [0, 0, 1, -20], [0, -1, 0, 0], [0, 0, 0, 1.0]])
    K = np.array([[50, 0, 32], [0, 50, 24], [0, 0, 1.0]])
    normals = np.tile([0, 0, 1.0], (500, 1))
    visible_points(SceneGeometry([ground]), sim_points, normals, np.zeros(500, np.int32), pose, K, 64, 48)
    visible_from(SceneGeometry([ground]), sim_points, normals, np.zeros(500, np.int32), np.zeros(3))
    fma = re.compile(r"^\s*(v?f(n)?m(add|sub)\w*|fml[as]\w*)\s", re.MULTILINE | re.IGNORECASE)
    exact_kernels.rows_times(np.ones((2, 3)), np.eye(3), np.empty((2, 3)))
    exact_kernels.batch_rows_times(np.ones((2, 3)), np.ones((2, 3, 3)), np.empty((2, 3)))
    SceneGeometry([ground]).cast_with_normals(np.zeros((2, 3)), np.array([[0, 0, -1.0], [0.1, 0, -1]]))  # proposed_hits
    exact_kernels.plane_hits(np.zeros((2, 3)), np.ones((2, 3)), np.eye(3, dtype=np.float32), np.zeros((2, 3), np.int32),
                             np.empty(2), np.empty((2, 3)), np.empty(2), True)
    exact_kernels.farther_than(np.ones(2), np.ones((2, 3)), 1.0)  # which rays the moving parts may meet
    near_distance.near_distances(np.zeros((2, 3)), np.eye(3)[None], 1.0)  # the timeline's exact distances
    near_distance.point_triangle_sq(0.5, 0.5, 0.5, np.eye(3))
    index, ones = np.zeros(2, np.int64), np.ones((2, 3))
    lidar_kernels.posed_rays(ones, index, np.ones((1, 4, 4)), np.empty((2, 3)), np.empty((2, 3)))  # a sweep's
    physics.returns(index, index, index, np.ones(1), ones.astype(np.float32), ones, index, np.ones(2), np.ones(2),
                    np.ones(5), np.empty(2, np.int64), np.empty(2), np.empty(2), np.empty(2, np.float32))
    lidar_kernels.return_points(index, ones, ones, ones, np.ones(2), np.ones(2), np.eye(4), np.empty((2, 3)),
                                *[np.empty((2, 3), np.float32)] * 3)
    for kernel in (kernels.select_rays, kernels.view_coords_of, kernels.segment_keep_of, omni_rays,
                   exact_kernels.rows_times, exact_kernels.batch_rows_times, exact_kernels.plane_hits,
                   exact_kernels.proposed_hits, exact_kernels.farther_than, near_distance.point_triangle_sq, near_distance.cell_pairs,
                   lidar_kernels.posed_rays, physics.returns, lidar_kernels.return_points):
        if not kernel.signatures:
            kernel(*([np.ones(2)] * 3 + ([np.ones(3)] * 3 if kernel is kernels.view_coords_of else [])))
        # numba shows no code of a function loaded from its disk cache: compile it afresh,
        # with the same options
        fresh = numba.njit(**{k: v for k, v in kernel.targetoptions.items() if k not in ("cache", "nopython")})(
            kernel.py_func)
        for sig in kernel.signatures:
            fresh.compile(sig)
            asm = fresh.inspect_asm(sig)
            assert "ret" in asm and "mul" in asm and not fma.search(asm), kernel


@pytest.fixture(scope="module")
def small_site(tmp_path_factory):
    from generator.scene import build_site

    result = build_site(3, "small", tmp_path_factory.mktemp("site"), preview=False, frames=20)
    return Simulator(result.blend, points_density=20.0, seed=0, max_pcl_depth=60.0)


def test_tile_ordered_rays_equal_one_ray_per_point_on_a_site(small_site):
    """The fast path (rays in screen-tile order) gives exactly the ray-per-point answer on a
    generated site, from the poses of its orbit and spline trajectories."""
    from generator.batch.config import plan_trajectory

    sim = small_site
    geo = SceneGeometry(sim.scene_parts())
    points, _, _ = sim.compute_point_cloud(update_mask=False)
    poses = []
    for kind in ("orbit", "spline"):
        poses += list(plan_trajectory(kind, sim, sim.spawn_points, sim.get_world_from_camera(), 0, 12, sim.fps).poses)
    limits = ViewLimits(sim.clip_start, min(sim.clip_end, sim.max_pcl_depth))
    visible = hidden = 0
    for pose in poses:
        args = (geo, points, None, None, pose, sim.K, sim.width, sim.height, limits)
        fast = visible_points(*args)
        ref = visible_points(*args, ray_per_point=True)
        assert np.array_equal(fast, ref)
        uv, z = cam_project(points, pose, sim.K)
        in_view = (z > limits.near) & (z <= limits.far) & (uv[:, 0] >= 0) & (uv[:, 0] < sim.width) & (
            uv[:, 1] >= 0) & (uv[:, 1] < sim.height)
        visible += int(fast.sum())
        hidden += int((in_view & ~fast).sum())
    assert visible > 1000 and hidden > 1000  # both answers are exercised


def test_blocks_and_reused_answers_equal_one_ray_per_point_while_exploring(small_site):
    """The Simulator's path (point blocks culled against the frustum, answers reused while the
    camera turns on the spot, forgotten when it moves or the frame changes) gives exactly the
    ray-per-point answer along a walk of moves, turns and frame changes."""
    sim = small_site
    sim.respawn_camera()
    rng = np.random.default_rng(5)
    limits = ViewLimits(sim.clip_start, min(sim.clip_end, sim.max_pcl_depth))
    turned = visible = in_view = one_by_one = 0
    for step in range(30):
        action = rng.integers(0, 3)
        if action == 0:
            sim.move_camera_forward(1.5)
        elif action == 1:
            sim.turn_camera_right(float(rng.choice([-20.0, 20.0])))
            turned += 1
        else:
            sim.set_frame(int(rng.integers(*sim.frame_range)))
        points, _, vis = sim.compute_point_cloud(update_mask=False)
        # the reference from public data only: fresh structures, every point, storage order
        geo = SceneGeometry(sim.scene_parts())
        sample = sim.surface_sample()
        ref_points = SurfacePoints.from_arrays(geo.parts, sample["local"], sample["local_normals"], sample["part"],
                                               sample["labels"])
        assert np.array_equal(ref_points.world, points)
        ref = visible_points(geo, ref_points.world, ref_points.world_normals, ref_points.part,
                             sim.get_world_from_camera(), sim.K, sim.width, sim.height, limits, ray_per_point=True)
        assert np.array_equal(vis, ref)
        visible += int(vis.sum())
        in_view += sim.last_visibility.in_view
        one_by_one += sim.last_visibility.tested_one_by_one
    assert turned > 3 and visible > 1000
    assert 0 < one_by_one < 0.9 * in_view  # the groups settle rules 1-3 for most points in view
