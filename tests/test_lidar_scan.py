"""LiDAR sweeps cast into small scenes built in code (generator/lidar/scanner.py, physics.py,
motion.py): returns on the surface with the right labels, noise of the stated sigma,
intensity and drop-outs as docs/lidar.md states them, glass passed, and a truck driving past
a spinning sensor seen where it was when each beam met it."""

import math
from dataclasses import replace

import numpy as np
import pytest

from generator.geometry.parts import MeshPart
from generator.geometry.raycast import SceneGeometry
from generator.lidar import physics
from generator.geometry.motion import MotionTrack
from generator.lidar.scanner import Scanner
from generator.lidar.sensors import lidar

BOX_FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                      [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])


def box(name, label, lo, hi, **kw):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=np.float64)
    return MeshPart(name, label, v, BOX_FACES.copy(), closed=True, **kw)


def quad(name, label, corners, **kw):
    return MeshPart(name, label, np.asarray(corners, dtype=np.float64), np.array([[0, 1, 2], [0, 2, 3]]), **kw)


def still(pose):
    return MotionTrack(np.array([0.0]), np.asarray(pose, dtype=np.float64)[None])


def at(x, y, z, yaw_deg=0.0):
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    m = np.eye(4)
    m[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    m[:3, 3] = (x, y, z)
    return m


def exact_distance(points, part):
    """Float64 distance from each point to the nearest triangle of ``part`` (closest point on
    each triangle, Ericson's regions), for checks finer than Embree's float32."""
    best = np.full(len(points), np.inf)
    v = part.world_vertices()
    for a, b, c in v[part.faces]:
        ab, ac, ap = b - a, c - a, points - a
        d1, d2 = ap @ ab, ap @ ac
        bp = points - b
        d3, d4 = bp @ ab, bp @ ac
        cp = points - c
        d5, d6 = cp @ ab, cp @ ac
        va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
        denom = va + vb + vc
        q = a + np.outer(vb / denom, ab) + np.outer(vc / denom, ac)  # inside: the plane's foot
        for mask, foot in (
            ((d1 <= 0) & (d2 <= 0), np.broadcast_to(a, points.shape)),
            ((d3 >= 0) & (d4 <= d3), np.broadcast_to(b, points.shape)),
            ((d6 >= 0) & (d5 <= d6), np.broadcast_to(c, points.shape)),
            ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + np.outer(d1 / np.where(d1 - d3 == 0, 1, d1 - d3), ab)),
            ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + np.outer(d2 / np.where(d2 - d6 == 0, 1, d2 - d6), ac)),
            ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
             b + np.outer((d4 - d3) / np.where((d4 - d3) + (d5 - d6) == 0, 1, (d4 - d3) + (d5 - d6)), c - b)),
        ):
            q = np.where(mask[:, None], foot, q)
        best = np.minimum(best, np.linalg.norm(points - q, axis=1))
    return best


def scanner(parts, seed=0):
    geometry = SceneGeometry(parts)
    labels = {name: i for i, name in enumerate(sorted({p.label for p in parts}))}
    return Scanner(geometry, np.array([labels[p.label] for p in parts]), np.arange(len(parts)), seed), labels


def yard():
    """Ground, a building block and a container."""
    return [quad("ground", "Ground", [(-60, -60, 0), (60, -60, 0), (60, 60, 0), (-60, 60, 0)]),
            box("block", "Building", (8, -6, 0), (16, 6, 9)),
            box("container", "Container", (-10, 3, 0), (-4, 5.4, 2.6))]


def test_without_noise_every_return_lies_on_the_surface_of_the_part_it_is_labelled_with():
    parts = yard()
    sc, labels = scanner(parts)
    sensor = replace(lidar("vlp16"), range_noise_sigma_m=0.0)
    sweep = sc.sweep(sensor, 0, 0.0, still(at(0, 0, 1.8, 30)))
    scan, world = sweep.scan, sweep.world
    assert len(scan) > 10_000
    per_part = np.stack([exact_distance(world, p) for p in parts], axis=1)
    assert per_part.min(axis=1).max() < 1e-5
    assert np.allclose(scan.xyz_exact, scan.xyz_deskewed, atol=1e-6)  # without noise: the same points
    # the float32 points of the files: within their rounding of the float64 ones
    assert np.abs(scan.world_points() - world).max() < 4 * np.abs(world).max() * 2.0**-24 + 1e-6
    nearest = per_part.argmin(axis=1)
    assert np.array_equal(scan.instance, nearest)
    assert np.array_equal(scan.label, [labels[parts[i].label] for i in nearest])
    assert set(np.unique(scan.instance)) == {0, 1, 2}
    # the raw and de-skewed points agree for a still sensor and a still scene; a return's
    # range lies in the sensor's limits
    assert np.allclose(scan.xyz, scan.xyz_deskewed, atol=1e-4)
    r = np.linalg.norm(scan.xyz.astype(np.float64), axis=1)
    assert r.min() >= sensor.range_min_m and r.max() <= sensor.range_max_m


def test_range_noise_has_the_stated_sigma_and_the_same_seed_the_same_bytes():
    parts = yard()
    sensor = lidar("os1-128")
    exact = scanner(parts)[0].sweep(replace(sensor, range_noise_sigma_m=0.0), 0, 0.0, still(at(0, 0, 1.8))).scan
    noisy = scanner(parts)[0].sweep(sensor, 0, 0.0, still(at(0, 0, 1.8))).scan
    again = scanner(parts)[0].sweep(sensor, 0, 0.0, still(at(0, 0, 1.8))).scan
    assert np.array_equal(noisy.xyz, again.xyz) and np.array_equal(noisy.intensity, again.intensity)
    key = lambda s: s.ring.astype(np.int64) * 10**7 + np.round(s.time * 1e6).astype(np.int64)  # noqa: E731
    common, a, b = np.intersect1d(key(exact), key(noisy), return_indices=True)
    assert len(common) > 0.95 * len(exact)
    residual = np.linalg.norm(noisy.xyz[b].astype(np.float64), axis=1) - np.linalg.norm(exact.xyz[a].astype(np.float64), axis=1)
    assert abs(residual.mean()) < 0.1 * sensor.range_noise_sigma_m
    assert residual.std() == pytest.approx(sensor.range_noise_sigma_m, rel=0.05)
    # the noise-free points kept beside the noisy ones are the noise-free sweep's
    assert np.allclose(noisy.xyz_exact[b], exact.xyz_deskewed[a], atol=1e-5)
    other = scanner(parts, seed=1)[0].sweep(sensor, 0, 0.0, still(at(0, 0, 1.8))).scan
    assert not np.array_equal(other.xyz[: len(noisy)], noisy.xyz[: len(other)])


def wall_scene(angle_deg, distance, reflectivity, glass_at=None):
    """A 40 m wide wall whose normal makes ``angle_deg`` with -x, crossing the x axis at
    ``distance``; optionally a glass pane across the x axis at ``glass_at``."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    along = np.array([s, c, 0.0])  # the wall's direction in the ground plane (normal (-c, s, 0)... turned)
    centre = np.array([distance, 0.0, 0.0])
    corners = [centre - 20 * along + [0, 0, -5], centre + 20 * along + [0, 0, -5],
               centre + 20 * along + [0, 0, 5], centre - 20 * along + [0, 0, 5]]
    parts = [quad("wall", "Building", corners, face_reflectivity=np.full(2, reflectivity, np.float32))]
    if glass_at is not None:
        pane = [(glass_at, -3, -3), (glass_at, 3, -3), (glass_at, 3, 3), (glass_at, -3, 3)]
        parts.append(quad("pane", "Neighbour", pane, face_transparent=np.ones(2, bool)))
    return parts, np.array([c, -s, 0.0])  # the wall's unit normal (up to sign)


def test_intensity_is_reflectivity_times_cos_incidence_and_grazing_beams_drop():
    sensor = replace(lidar("vlp16"), range_noise_sigma_m=0.0)
    for angle in (0.0, 40.0, 70.0):
        parts, normal = wall_scene(angle, 10.0, 0.6)
        scan = scanner(parts)[0].sweep(sensor, 0, 0.0, still(at(0, 0, 0))).scan
        d = scan.xyz.astype(np.float64)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        cos = np.abs(d @ normal)
        assert len(scan) > 50 and np.allclose(scan.intensity, 0.6 * cos, atol=1e-6)
        assert np.degrees(np.arccos(cos)).max() <= sensor.max_incidence_deg + 1e-9
    # a wall seen almost edge-on: the beams that meet it past the grazing limit report nothing
    parts, normal = wall_scene(88.0, 10.0, 0.9)
    sc = scanner(parts)[0]
    scan = sc.sweep(sensor, 0, 0.0, still(at(0, 0, 0))).scan
    d = scan.xyz.astype(np.float64) / np.linalg.norm(scan.xyz.astype(np.float64), axis=1, keepdims=True)
    assert np.all(np.abs(d @ normal) >= math.cos(math.radians(sensor.max_incidence_deg)) - 1e-9)


def test_a_dark_target_drops_past_the_range_of_a_ten_percent_target():
    sensor = replace(lidar("vlp16"), range_noise_sigma_m=0.0)
    r10 = sensor.range_at_10pct_m
    seen = []
    for distance in (0.9 * r10, 1.1 * r10):
        parts, _ = wall_scene(0.0, distance, 0.1)
        scan = scanner(parts)[0].sweep(sensor, 0, 0.0, still(at(0, 0, 0))).scan
        straight = np.abs(scan.xyz[:, 1]) < 0.02 * distance  # beams within about 1 degree of the normal
        seen.append(int(straight.sum()))
    assert seen[0] > 0 and seen[1] == 0
    parts, _ = wall_scene(0.0, 1.1 * r10, 0.5)  # a brighter one is still seen there
    assert len(scanner(parts)[0].sweep(sensor, 0, 0.0, still(at(0, 0, 0))).scan) > 0


def test_glass_returns_nothing_and_what_lies_behind_is_dimmed_by_its_transmission():
    sensor = replace(lidar("vlp16"), range_noise_sigma_m=0.0)
    parts, normal = wall_scene(0.0, 12.0, 0.5, glass_at=5.0)
    scan = scanner(parts)[0].sweep(sensor, 0, 0.0, still(at(0, 0, 0))).scan
    assert not np.any(np.abs(scan.xyz[:, 0] - 5.0) < 1e-3)  # no return on the pane
    behind = (np.abs(scan.xyz[:, 1]) < 2.5) & (np.abs(scan.xyz[:, 2]) < 2.0)  # through the pane
    assert behind.sum() > 20 and np.allclose(scan.xyz[behind, 0], 12.0, atol=1e-4)
    d = scan.xyz[behind].astype(np.float64)
    cos = np.abs(d @ normal) / np.linalg.norm(d, axis=1)
    tau = physics.GLASS_TRANSMISSION ** 2
    assert np.allclose(scan.intensity[behind], 0.5 * cos * tau, atol=1e-6)
    beside = np.abs(scan.xyz[:, 1]) > 7.5  # beams that passed beside the pane (its edge at y = 3 at x = 5)
    assert np.allclose(scan.intensity[beside], 0.5 * np.abs(scan.xyz[beside].astype(np.float64) @ normal)
                       / np.linalg.norm(scan.xyz[beside].astype(np.float64), axis=1), atol=1e-6)


def test_a_pane_flush_on_a_wall_is_crossed_and_the_wall_behind_it_stops_the_beam():
    """A window as the neighbours' buildings have them: a 6 cm glass box whose back face lies
    on a solid block's wall. Beams through it return from the wall (never from inside the
    block), dimmed by both of the pane's faces."""
    sensor = replace(lidar("vlp16"), range_noise_sigma_m=0.0)
    block = box("block", "Building", (10, -20, -5), (30, 20, 5), face_reflectivity=np.full(12, 0.5, np.float32))
    pane = box("pane", "Building", (9.94, -3, -3), (10, 3, 3), face_transparent=np.ones(12, bool))
    scan = scanner([block, pane])[0].sweep(sensor, 0, 0.0, still(at(0, 0, 0))).scan
    behind = (np.abs(scan.xyz[:, 1]) < 2.5) & (np.abs(scan.xyz[:, 2]) < 2.0)  # through the pane
    assert behind.sum() > 20 and np.allclose(scan.xyz[behind, 0], 10.0, atol=1e-4)  # on the wall, not at x = 30
    d = scan.xyz[behind].astype(np.float64)
    cos = np.abs(d[:, 0]) / np.linalg.norm(d, axis=1)
    assert np.allclose(scan.intensity[behind], 0.5 * cos * physics.GLASS_TRANSMISSION ** 4, atol=1e-6)
    assert not np.any(scan.xyz[:, 0] > 10.0 + 1e-4)


def test_a_truck_driving_past_is_seen_where_it_was_when_each_beam_met_it():
    """A 10 m/s truck 8 m from a spinning sensor that itself drives at 5 m/s: a return at
    time t lies on the truck at its pose at t (within the stated motion bound); the de-skewed
    sweep lies on the truck at the sweep's start."""
    sensor = replace(lidar("vlp16"), range_noise_sigma_m=0.0)
    truck = box("truck", "Truck", (-4, -1.25, 0), (4, 1.25, 3.5), dynamic=True)
    ground = quad("ground", "Ground", [(-80, -80, 0), (80, -80, 0), (80, 80, 0), (-80, 80, 0)])
    parts = [ground, truck]
    times = np.array([0.0, 0.1, 0.2])
    path = MotionTrack(times, np.stack([at(-3 + 10 * t, 8, 0) for t in times]))
    body = MotionTrack(times, np.stack([at(5 * t, 0, 1.8) for t in times]))
    sc, _ = scanner(parts)
    sweep = sc.sweep(sensor, 0, 0.05, body, {1: path})
    scan = sweep.scan
    on = scan.instance == 1
    assert on.sum() > 100 and 0 < sweep.motion_bound_m <= 0.01 and sweep.slices > 1
    # each return against the truck at its own time (the sensor's pose at that time too)
    t = 0.05 + scan.time[on].astype(np.float64)
    sensor_at = body.at(t)
    world = np.einsum("nij,nj->ni", sensor_at[:, :3, :3], scan.xyz[on].astype(np.float64)) + sensor_at[:, :3, 3]
    truck_at = path.at(t)
    local = np.einsum("nji,nj->ni", truck_at[:, :3, :3], world - truck_at[:, :3, 3])
    d = SceneGeometry([replace(truck, dynamic=False, matrix=np.eye(4))]).distance(local)
    assert d.max() <= sweep.motion_bound_m + 1e-4
    # had the truck stood still at the sweep's start, the raw returns would miss it by over 10 cm
    start = path.at(0.05)[0]
    skewed = np.einsum("ji,nj->ni", start[:3, :3], world - start[:3, 3])
    assert SceneGeometry([replace(truck, dynamic=False, matrix=np.eye(4))]).distance(skewed).max() > 0.1
    # the de-skewed sweep: the scene frozen at the sweep's start
    frozen = np.einsum("ji,nj->ni", start[:3, :3], scan.world_points()[on] - start[:3, 3])
    assert SceneGeometry([replace(truck, dynamic=False, matrix=np.eye(4))]).distance(frozen).max() <= 1e-4
    ground_points = scan.world_points()[scan.instance == 0]
    assert np.abs(ground_points[:, 2]).max() < 1e-4
