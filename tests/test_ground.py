"""What the ground is made of (generator/scene/catalogue/ground.py, generator/blender/ground.py):
drawn per seed deterministically, five surfaces over seeds 0-99, recorded in site.json,
overridable; the road is painted where the plan's road runs; the pixels change with the
surface, the ground truth does not."""

import json
import subprocess
import sys
from collections import Counter

import numpy as np
import pytest

from conftest import ROOT, assert_refused
from generator.scene.catalogue.ground import ROADS, SURFACES, choose_ground
from generator.scene.weather import choose_weather


def test_the_ground_is_drawn_per_seed_deterministically_and_an_override_keeps_the_road():
    a = choose_ground(12)
    assert a == choose_ground(12) and a.surface in SURFACES and a.road in ROADS
    for name in SURFACES:
        g = choose_ground(12, name)
        assert g.surface == name and g.road == a.road and g.material == f"ground-{name}"
    assert choose_weather(12) == choose_weather(12)  # its own stream: the weather's draws are untouched
    with pytest.raises(ValueError, match="^unknown ground surface 'snow'; choose one of compacted-soil, mud"):
        choose_ground(12, "snow")


def test_seeds_0_to_99_cover_five_surfaces_each_on_a_tenth_of_them():
    drawn = [choose_ground(seed) for seed in range(100)]
    surfaces, roads = Counter(g.surface for g in drawn), Counter(g.road for g in drawn)
    assert set(surfaces) == set(SURFACES) and len(surfaces) >= 5 and min(surfaces.values()) >= 10, surfaces
    assert set(roads) == set(ROADS), roads


def test_an_unknown_ground_is_one_line_and_exit_2(tmp_path):
    for module in ("generator", "generator.scene --seed 1"):
        assert_refused(subprocess.run([sys.executable, "-m", *module.split(), "--out", str(tmp_path / "x"), "--ground",
                                       "snow"], capture_output=True, text=True, cwd=ROOT), "--ground", "dry-dust")


def test_the_ground_is_one_surface_cut_into_its_regions():
    """Every face turned to the air, the faces seen from above covering the ground's square
    exactly once (the relief included); the site's surface and the road level at z = 0, the
    tracks too or sunk as ruts; road and tracks along the plan's road (or on the gate access),
    the site's surface off it, grass beyond the fence."""
    from generator.scene.catalogue.ground import GROUND_MARGIN
    from generator.scene.ground_layout import TRACK_OFFSET_M
    from generator.scene.site import GATE, plan_site, site_ground, site_params

    for seed, preset in ((1, "small"), (1, "medium"), (3, "medium")):  # a concrete road; a rutted one
        plan = plan_site(seed, site_params(preset, frames=20))
        mesh = site_ground(plan).mesh
        v = mesh.vertices
        faces = list(mesh.quads) + list(mesh.tris)
        x, y = [np.array([v[f, k] for f in faces], dtype=object) for k in (0, 1)]
        area = np.array([0.5 * np.sum(a * np.roll(b, -1) - np.roll(a, -1) * b) for a, b in zip(x, y)])
        assert area.min() >= 0 and np.mean(area > 0) > 0.99  # counter-clockwise from above (dig walls: vertical)
        side = plan.params.size + 2 * GROUND_MARGIN
        assert area.sum() == pytest.approx(side * side, rel=1e-12)
        centroid = np.array([v[f, :2].mean(axis=0) for f in faces])
        material = np.array([mesh.materials[i] for i in mesh.face_material])
        ground = plan.ground
        d = distance_to_polyline(centroid, plan.road)
        half = plan.params.size / 2
        gate = (centroid[:, 0] > GATE[0]) & (centroid[:, 0] < GATE[1]) & (centroid[:, 1] < 0)
        paved = ground.road_material != ground.material  # a rutted road is the site's surface with tracks
        assert paved == (seed == 1)
        on_road = np.isin(material, [ground.road_material, ground.tracks_material] if paved else [ground.tracks_material])
        assert on_road.any() and (material == ground.tracks_material).any()
        assert np.all((d[on_road] < plan.road_width / 2) | gate[on_road])
        tracks = (material == ground.tracks_material) & ~gate
        assert np.all(np.abs(d[tracks] - TRACK_OFFSET_M) < 0.5)
        surface = material == ground.material
        assert np.all(np.abs(centroid[surface]).max(axis=1) < half)
        z = np.array([v[f, 2].max() - 0 for f in faces]), np.array([v[f, 2].min() for f in faces])
        level = surface | (material == ground.road_material)
        assert np.all(z[0][level] == 0.0) and np.all(z[1][level] == 0.0)
        ruts = ground.rut_depth
        assert (ruts == 0.0) == paved and np.all(np.isin(z[1][material == ground.tracks_material], [0.0, -ruts]))
        if paved:
            assert np.all(d[surface] > 0.3) and not gate[surface & (np.abs(centroid[:, 1]) > half - 2)].any()
        assert np.all(np.abs(centroid[material == "grass"]).max(axis=1) > half)


def distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """(N,) distance of 2D ``points`` to the closed polyline ``line`` (K, 2)."""
    a, b = line, np.roll(line, -1, axis=0)
    ab = b - a
    t = np.clip(((points[:, None] - a) * ab).sum(-1) / (ab * ab).sum(-1).clip(1e-12), 0, 1)
    nearest = a + t[..., None] * ab
    return np.linalg.norm(points[:, None] - nearest, axis=-1).min(axis=1)


@pytest.fixture(scope="module")
def looks(tmp_path_factory):
    """Seed 5's small site (its road: asphalt) with two surfaces, one view from above the
    south-west corner of its road loop at 64x48: surface -> (site, simulator, render)."""
    from generator import Simulator
    from generator.geometry.camera import look_at
    from generator.scene import build_site

    out = {}
    for surface in ("gravel", "clay"):
        site = build_site(5, "small", tmp_path_factory.mktemp(surface), preview=False, ground=surface)
        sim = Simulator(site.blend, points_density=0.05, seed=5, render_preset="preview")
        sim.configure_render(resolution=(64, 48))
        corner = site.plan.road[np.argmin(site.plan.road.sum(axis=1))]
        eye = np.array([corner[0] + 6.0, corner[1] + 6.0, 14.0])
        sim.set_world_from_camera(look_at(eye, np.array([corner[0], corner[1], 0.0])), check_collisions=False)
        out[surface] = (site, sim, sim.render())
    return out


def test_site_json_records_the_ground_and_the_ground_truth_does_not_change(looks):
    (site_g, sim_g, g), (site_c, sim_c, c) = looks["gravel"], looks["clay"]
    for site, name in ((site_g, "gravel"), (site_c, "clay")):
        recorded = json.loads((site.blend.parent / "site.json").read_text())
        assert recorded["ground"] == {"surface": name, "road": "asphalt"} and recorded["params"]["ground"] == name
    for key in ("depth", "seg", "instance"):
        np.testing.assert_array_equal(getattr(g, key), getattr(c, key), err_msg=key)
    np.testing.assert_array_equal(sim_g.point_positions, sim_c.point_positions)
    ground, d, world = road_distance(site_g, sim_g, g)
    off = (d > 5.0) & (np.abs(world[:, :2]).max(axis=1) < site_g.plan.params.size / 2)  # the site's surface
    assert off.sum() > 100
    # clay is red, gravel grey: the mean red share of the site surface's pixels tells them apart
    red = [(v.rgb_linear[ground][off, 0] / v.rgb_linear[ground][off].sum(axis=1).clip(1e-6)).mean() for v in (g, c)]
    assert red[1] > red[0] + 0.05, red


def road_distance(site, sim, view):
    """(mask of the ground's pixels, each one's distance (m) to the plan's road centre line)."""
    ground = (view.seg == 0) & np.isfinite(view.depth)
    h, w = view.depth.shape
    u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    K, pose = view.K, sim.get_world_from_camera()
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)  # OpenCV camera
    world = (rays[ground] * view.depth[ground][:, None]) @ pose[:3, :3].T + pose[:3, 3]
    level = np.abs(world[:, 2]) < 0.05  # the working level (not a spoil heap, a dig or the terrain)
    assert level.mean() > 0.5  # (the view takes in the terrain beyond the fence)
    ground[ground] = level
    return ground, distance_to_polyline(world[level, :2], site.plan.road), world[level]


def test_the_asphalt_road_is_where_the_plan_puts_the_road(looks):
    site, sim, view = looks["gravel"]
    ground, d, _ = road_distance(site, sim, view)
    brightness = view.rgb_linear[ground].mean(axis=1)
    on, off = brightness[d < 2.5], brightness[(d > 5.0) & (d < 9.0)]
    assert len(on) > 50 and len(off) > 50, (len(on), len(off))
    assert np.median(on) < 0.65 * np.median(off), (np.median(on), np.median(off))  # dark asphalt on grey gravel
