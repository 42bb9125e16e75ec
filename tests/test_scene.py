"""The procedural site generator: determinism, physical plausibility, motion, taxonomy."""

import json
import math
import os
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import bpy
import numpy as np
import pytest

from generator import Simulator
from generator.geometry.parts import MeshPart, closed_and_orientation
from generator.geometry.raycast import SceneGeometry
from generator.geometry.sampling import sample_triangles
from generator.scene import CLASSES, build_site, plan_site, site_params
from generator.blender.extract import SCENERY_PROPERTY
from generator.scene.kinds import all_kinds
from generator.scene.planning import Mix

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def small_site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    result = build_site(7, "small", out, preview=False, frames=60)
    return result


def _asset_triangles():
    """World triangles of every placed asset of the open file at the current frame, by asset
    index (-1: ground and fence), with each object's closedness; not the scenery beyond the
    fence (it stands on the terrain there: tests/test_surroundings.py)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out: dict[int, list] = {}
    for obj in bpy.data.objects:
        if obj.type != "MESH" or obj.name == "CameraSpawn" or obj.get(SCENERY_PROPERTY):
            continue
        ev = obj.evaluated_get(depsgraph)
        me = ev.data
        me.calc_loop_triangles()
        co = np.empty(len(me.vertices) * 3, np.float64)
        me.vertices.foreach_get("co", co)
        m = np.array(ev.matrix_world)
        v = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
        f = np.empty(len(me.loop_triangles) * 3, np.int64)
        me.loop_triangles.foreach_get("vertices", f)
        f = f.reshape(-1, 3)
        key = -2 if obj.name.startswith("Ground") else int(obj.get("buildee_asset", -1))
        out.setdefault(key, []).append((obj.name, v, f))
    return out


def test_same_seed_same_site_across_processes(tmp_path):
    code = textwrap.dedent(
        """
        import hashlib, sys
        import bpy, numpy as np
        from generator.scene import build_site
        build_site(int(sys.argv[1]), "small", sys.argv[2], preview=False, frames=40)
        h = hashlib.sha256()
        dg = bpy.context.evaluated_depsgraph_get()
        for obj in sorted(bpy.data.objects, key=lambda o: o.name):
            h.update(obj.name.encode())
            if obj.type == "MESH":
                ev = obj.evaluated_get(dg)
                co = np.array([ev.matrix_world @ v.co for v in ev.data.vertices])
                h.update(np.round(co, 5).astype(np.float64).tobytes())
        print(h.hexdigest())
        """
    )
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}

    def run(seed, folder, hashseed):
        env["PYTHONHASHSEED"] = str(hashseed)
        r = subprocess.run([sys.executable, "-c", code, str(seed), str(tmp_path / folder)], capture_output=True,
                           text=True, cwd=ROOT, env=env)
        assert r.returncode == 0, r.stderr[-2000:]
        return r.stdout.strip().splitlines()[-1]

    a, b, c = run(11, "a", 1), run(11, "b", 2), run(12, "c", 1)
    assert a == b
    assert a != c
    assert (tmp_path / "a" / "site.json").read_text() == (tmp_path / "b" / "site.json").read_text()


def test_saved_site_loads_with_taxonomy_ids(small_site):
    sim = Simulator(small_site.blend, points_density=0.5)
    assert sim.labels[: len(CLASSES)] == list(CLASSES)  # ids are the taxonomy's, stable across sites
    assert sim.labels == list(CLASSES)
    _, labels, _ = sim.compute_point_cloud(update_mask=False)
    present = {sim.labels[i] for i in np.unique(labels)}
    assert {"Ground", "Fence", "Building", "Truck"} <= present
    # the CameraSpawn volume is not rendered, yet gives spawn points above the whole site
    sp = sim.spawn_points
    assert len(sp) > 500 and sp[:, 2].min() >= 1.5 - 1e-9
    assert np.ptp(sp[:, 0]) > 40 and np.ptp(sp[:, 1]) > 40  # a 50 m site
    info = json.loads((small_site.blend.parent / "site.json").read_text())
    assert info["objects"] > 20 and info["triangles"] > 10_000


def test_objects_rest_on_ground_and_do_not_intersect(small_site):
    sim = Simulator(small_site.blend, points_density=0.1)  # loads the saved site
    rng = np.random.default_rng(0)
    checked = 0
    for frame in (1, 30, 60):
        bpy.context.scene.frame_set(frame)
        assets = _asset_triangles()
        parts = {}
        for key, objects in assets.items():
            v = np.concatenate([o[1] for o in objects])
            assert key == -2 or v[:, 2].min() >= -1e-4, f"asset {key} ({objects[0][0]}) goes below the ground at frame {frame}"
            if key >= 0:
                assert v[:, 2].min() <= 0.01, f"asset {key} ({objects[0][0]}) floats {v[:, 2].min():.3f} m above the ground"
            offset, faces = 0, []
            for _, vo, fo in objects:
                faces.append(fo + offset)
                offset += len(vo)
            f = np.concatenate(faces)
            closed, outward = closed_and_orientation(v, f)
            parts[key] = MeshPart(str(key), objects[0][0], v, f, closed=closed, outward=outward)
        keys = [k for k in parts if k != -2]
        for i, a in enumerate(keys):
            for b in keys[i + 1:]:
                hit = _touches(parts[a], parts[b], rng)
                if hit is None:
                    continue
                checked += 1
                assert not hit, f"{parts[a].label} (asset {a}) touches or enters {parts[b].label} (asset {b}) at frame {frame}"
        # negative control: the same check flags an asset moved 0.2 m into itself
        some = parts[keys[0]]
        shifted = MeshPart("shifted", some.label, some.vertices + [0.2, 0.0, 0.0], some.faces, closed=some.closed, outward=some.outward)
        assert _touches(some, shifted, rng) is True
    assert checked > 0


def test_surface_points_lie_on_surfaces_cameras_can_reach(small_site):
    """The ground is one open surface turned to the air, level at z = 0 but for its relief; no
    surface point but the ground's lies below the level (beyond 5 cm) or on a face resting on
    it, in the Simulator's points and in the scoring cloud."""
    from exporters.ground_truth import sample_scoring_points
    from generator.geometry.sampling import CONTACT_TOLERANCE, contact_faces, ground_height

    sim = Simulator(small_site.blend, points_density=5.0)
    parts = sim.scene_parts()
    ground = [p for p in parts if p.label == "Ground" and not p.closed and not p.scenery]
    assert len(ground) == 1 and len(ground[0].faces) > 2  # cut where its material changes
    assert ground_height(parts) == 0.0 and ground[0].vertices[:, 2].min() < -0.03  # ruts at least
    v, f = ground[0].vertices, ground[0].faces
    up = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])[:, 2]
    assert np.all(up >= 0) and np.mean(up > 0) > 0.99  # faces turned to the air (dig walls: vertical)
    # the faces the rule drops exist (bottoms of props), and face straight down at z = 0
    dropped: dict[str, int] = {}
    for p in parts:
        dropped[p.label] = dropped.get(p.label, 0) + int(contact_faces(p, 0.0).sum())
    assert sum(dropped.values()) > 20 and not contact_faces(ground[0], 0.0).any()
    assert {"Container", "Cabin"} & {k for k, v in dropped.items() if v}
    pts, labels, _ = sim.compute_point_cloud(update_mask=False)
    normals = sim.surface_sample()["local_normals"]  # static parts: world frame
    static = ~sim.dynamic_points_mask
    scoring = sample_scoring_points(parts, sim.label_ids, 20.0, 0)
    for xyz, nrm, on_ground in ((pts[static], normals[static], labels[static] == sim.label_ids["Ground"]),
                                (scoring["xyz"], scoring["normals"], scoring["label"] == sim.label_ids["Ground"])):
        assert xyz[~on_ground, 2].min() >= -0.05
        low = (xyz[:, 2] <= CONTACT_TOLERANCE) & ~on_ground
        assert not np.any(low & (nrm[:, 2] < -0.99)), "points on a face resting on the ground"
        assert on_ground.sum() > 0.3 * len(xyz)
    # negative control: without the rule, the same sampling puts points on those faces
    bottoms = [p for p in parts if contact_faces(p, 0.0).any()]
    raw, _ = sample_triangles(bottoms[0].vertices, bottoms[0].faces[contact_faces(bottoms[0], 0.0)], 50.0,
                              np.random.default_rng(0))
    assert len(raw) > 0 and np.all(np.abs(raw[:, 2]) <= CONTACT_TOLERANCE)


def _touches(a: MeshPart, b: MeshPart, rng) -> bool | None:
    """True if surface samples of ``a`` near ``b`` (300 a square metre, fewer where more
    than 67 m² of ``a`` lie in ``b``'s box: a building beside a rebar bundle) or the corners
    of its triangles there come within 1 mm of ``b`` or lie inside it; None if their
    bounding boxes are apart (nothing to check)."""
    alo, ahi, blo, bhi = a.vertices.min(0), a.vertices.max(0), b.vertices.min(0), b.vertices.max(0)
    if np.any(alo > bhi + 0.01) or np.any(blo > ahi + 0.01):
        return None
    tri = a.vertices[a.faces]  # only A's triangles near B need a look
    near = np.all(tri.max(axis=1) >= blo - 0.01, axis=1) & np.all(tri.min(axis=1) <= bhi + 0.01, axis=1)
    if not near.any():
        return None
    e1, e2 = tri[near, 1] - tri[near, 0], tri[near, 2] - tri[near, 0]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()  # 300 points a m², at most 20,000 in all
    pts, _ = sample_triangles(a.vertices, a.faces[near], min(300.0, 20_000 / max(area, 1e-9)), rng)
    pts = np.concatenate([pts, tri[near].reshape(-1, 3)])  # and their corners
    geo_b = SceneGeometry([b])
    return bool(geo_b.distance(pts).min() <= 1e-3 or geo_b.inside_solid(pts).any())


def test_dynamic_objects_move_and_static_ones_do_not(small_site):
    sim = Simulator(small_site.blend, points_density=2.0)
    dyn = set(name.split(".")[0] for name in sim.dynamic_objects)
    assert "Truck" in dyn
    assert not dyn & {"Building", "Container", "Fence", "Ground", "SandPile", "GravelPile"}
    p0 = np.array(sim.compute_point_cloud()[0])
    mask = sim.dynamic_points_mask
    for _ in range(5):
        sim.step_frame()
    p1 = sim.compute_point_cloud()[0]
    assert np.array_equal(p0[~mask], p1[~mask])
    moved = np.linalg.norm(p1[mask] - p0[mask], axis=1)
    assert mask.sum() > 100 and np.median(moved) > 0.5  # trucks drive 3-5 m/s, 0.5 s later


def test_crane_and_excavator_are_dynamic(tmp_path):
    # a medium plan always holds a crane and an excavator; build it without the preview
    result = build_site(0, "medium", tmp_path, preview=False, frames=20, density=0.2)
    sim = Simulator(result.blend, points_density=0.05)
    dyn = {name.split(".")[0] for name in sim.dynamic_objects}
    assert {"Crane", "Excavator", "Truck"} <= dyn
    info = json.loads((tmp_path / "site.json").read_text())
    assert info["assets"]["Crane"] >= 1 and info["assets"]["Building"] >= 1


def test_crane_trolleys_travel_at_a_crane_speed_whatever_the_animation_length():
    """A trolley runs along its jib at no more than 1 m/s (real ones: 1-1.7 m/s), on a short
    animation as on the batch job's 250 frames; it used to cover the same distance in any
    animation length (28 m/s at 20 frames)."""
    moved = 0.0
    for frames in (20, 250):
        for seed in (0, 1, 2):
            params = site_params("medium", frames=frames)
            for placed in plan_site(seed, params).placed:
                if placed.asset.kind != "Crane":
                    continue
                keys = [p.keys for p in placed.asset.parts if p.keys is not None and p.keys.location is not None]
                assert len(keys) == 1  # the trolley (the hook hangs from it)
                t, x = (keys[0].frames - 1) / params.fps, keys[0].location[:, 0]
                assert t[0] == 0 and math.isclose(t[-1], (frames - 1) / params.fps) and np.all(np.diff(t) > 0)
                assert np.all(np.abs(np.diff(x)) <= 1.0 * np.diff(t) + 1e-9), f"trolley faster than 1 m/s, {frames} frames"
                moved = max(moved, np.ptp(x))
    assert moved > 5.0  # and it does travel


def test_scenery_is_in_the_scene_but_carries_no_points(small_site):
    """The surroundings (generator/scene/surroundings.py) are parts of the scene (rendered,
    in visibility and collisions) flagged as scenery: no surface point, no scoring point."""
    from exporters.ground_truth import sample_scoring_points

    sim = Simulator(small_site.blend, points_density=2.0)
    parts = sim.scene_parts()
    scenery = [i for i, p in enumerate(parts) if p.scenery]
    assert scenery and {parts[i].label for i in scenery} >= {"Ground", "Vegetation"}  # a street, trees or hedges
    assert not any(p.scenery for p in parts if p.label in ("Building", "Fence", "Crane"))
    assert len([p for p in parts if p.label == "Ground" and not p.scenery]) == 1
    assert not np.isin(sim.surface_sample()["part"], scenery).any()
    scoring = sample_scoring_points(parts, sim.label_ids, 5.0, 0)
    assert not np.isin(scoring["instance"], scenery).any() and len(scoring["xyz"]) > 1000
    # negative control: the same part unflagged gets points
    tree = parts[scenery[-1]]
    assert len(sample_scoring_points([replace(tree, scenery=False)], sim.label_ids, 5.0, 0)["xyz"]) > 0


def test_every_class_appears_across_a_few_seeds(medium_plans):
    seen = set()
    for plan in medium_plans.values():
        for placed in plan.placed:
            seen.update(p.label for p in placed.asset.parts if p.label)
        if plan.fence_runs:
            seen.add("Fence")
    seen.add("Ground")  # every site has its ground slab
    assert seen == set(CLASSES), f"missing: {set(CLASSES) - seen}"
    assert {k.name for k in all_kinds() if isinstance(k.place, Mix)} | {"Building", "Crane", "Truck", "Excavator"} >= {
        "Container", "Cabin", "BrickPallet"}


def test_plans_are_deterministic_and_seed_dependent():
    a, b, c = (plan_site(s, site_params("small")) for s in (5, 5, 6))
    fa = [(p.asset.kind, p.position, p.yaw) for p in a.placed]
    assert fa == [(p.asset.kind, p.position, p.yaw) for p in b.placed]
    assert fa != [(p.asset.kind, p.position, p.yaw) for p in c.placed]


@pytest.mark.parametrize(
    "preset,overrides,message",
    [
        ("huge", {}, "unknown scene preset"),
        ("medium", {"size": -10.0}, r"^site size must be a number of metres in \[30, 1000\], got -10.0$"),
        ("medium", {"size": math.nan}, r"^site size must be a number of metres in \[30, 1000\], got nan$"),
        ("medium", {"density": -1.0}, r"^object density must be a number in \[0, 5\], got -1.0$"),
        ("medium", {"layout": "spiral"}, "layout"),
        ("medium", {"phase": 1.5}, r"^construction phase must be a number in \[0, 1\], got 1.5$"),
        ("medium", {"phase": "0.5"}, r"^construction phase must be a number in \[0, 1\], got '0.5'$"),
        ("medium", {"frames": 0}, "^animation length must be an integer >= 2 frames, got 0$"),
        ("medium", {"frames": 250.0}, "^animation length must be an integer >= 2 frames, got 250.0$"),
        ("medium", {"fps": math.inf}, "^fps must be a finite number > 0, got inf$"),
    ],
)
def test_bad_parameters(preset, overrides, message):
    """One line naming the parameter, its valid values and the value given."""
    with pytest.raises(ValueError, match=message):
        site_params(preset, **overrides)


def test_cli_bad_preset_exits_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "generator.scene", "--seed", "0", "--preset", "huge", "--out", str(tmp_path)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and "invalid choice" in r.stderr
    r = subprocess.run([sys.executable, "-m", "generator.scene", "--seed", "0", "--size", "-5", "--out", str(tmp_path)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and r.stderr.strip().startswith("error: site size")
    assert "Traceback" not in r.stderr
