"""The LiDAR sensors declared once (generator/lidar/sensors.py, patterns.py), no Blender: each
spinning preset's beams are its data sheet's table, a sweep covers 360 degrees once clockwise
from behind, the rosette stays in its field of view, fills it and never repeats, the dome
covers its sphere at its step, the drone mount is a proper rotation pointing the rosette
down, bad names give one-line errors, the summary is JSON, and the same sensor gives the same
arrays. The tables below are written from the data sheets, not read from the code."""

import dataclasses
import json
import math

import numpy as np
import pytest

from generator.lidar import patterns
from generator.lidar.sensors import PRESETS, Lidar, body_directions, body_from_sensor, emission, lidar

SHEET_TABLES = {  # elevation of each beam in degrees, lowest first
    "vlp16": [float(e) for e in range(-15, 16, 2)],
    "hdl64": sorted([2.0 - k / 3.0 for k in range(32)] + [-8.83 - k / 2.0 for k in range(32)]),
    "os1-128": list(np.linspace(-22.5, 22.5, 128)),
}
COLUMNS = {"vlp16": 1800, "hdl64": 2083, "os1-128": 2048}


def angles_deg(d):
    """(azimuth, elevation) in degrees of unit vectors: azimuth counter-clockwise from +x."""
    d = np.asarray(d, dtype=np.float64)
    return np.degrees(np.arctan2(d[:, 1], d[:, 0])), np.degrees(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))


def one_line_error(call):
    with pytest.raises(ValueError) as caught:
        call()
    message = str(caught.value)
    assert message and "\n" not in message
    return message


@pytest.mark.parametrize("name", sorted(SHEET_TABLES))
def test_spinning_presets_reproduce_their_data_sheet_tables(name):
    sensor = lidar(name)
    table = SHEET_TABLES[name]
    assert sensor.kind == "spinning" and len(sensor.elevations_deg) == len(table)
    assert np.allclose(sensor.elevations_deg, table, rtol=0, atol=1e-9)
    assert sensor.columns == COLUMNS[name] and sensor.rate_hz == 10.0
    assert table[0] == min(table)  # ring 0: the lowest beam


@pytest.mark.parametrize("name", sorted(SHEET_TABLES))
def test_a_spinning_sweep_turns_once_clockwise_from_behind_with_each_ring_at_its_elevation(name):
    sensor = lidar(name)
    beams, columns = len(SHEET_TABLES[name]), COLUMNS[name]
    e = emission(sensor)
    assert len(e) == beams * columns and e.directions.shape == (beams * columns, 3)
    assert e.ring.dtype == np.uint16 and e.directions.dtype == np.float64 and e.time.dtype == np.float64
    assert np.allclose(np.linalg.norm(e.directions, axis=1), 1.0, rtol=0, atol=1e-12)
    azimuth, elevation = angles_deg(e.directions)
    assert np.allclose(elevation, np.asarray(SHEET_TABLES[name])[e.ring], rtol=0, atol=1e-9)
    assert np.array_equal(np.bincount(e.ring), np.full(beams, columns))
    for ring in (0, beams - 1):
        az = azimuth[e.ring == ring]
        assert abs(abs(az[0]) - 180.0) < 1e-9  # the sweep starts behind the sensor
        step = (np.diff(az) + 180.0) % 360.0 - 180.0
        assert np.allclose(step, -360.0 / columns, rtol=0, atol=1e-9)  # clockwise seen from above
        assert len(np.unique(np.round(az % 360.0, 6))) == columns  # every azimuth once
    t = e.time
    assert np.all(np.diff(t) >= 0) and t[0] == 0.0 and t[-1] < 1.0 / sensor.rate_hz
    assert len(np.unique(t)) == columns and np.all(t.reshape(columns, beams) == t[::beams, None])


def test_a_user_built_spinning_sensor_fires_its_columns_where_and_when_stated():
    sensor = Lidar(name="toy", kind="spinning", source="test", rate_hz=5.0, range_min_m=0.1, range_max_m=50.0,
                   range_noise_sigma_m=0.0, range_at_10pct_m=20.0, elevations_deg=(-10.0, 0.0, 30.0), columns=4)
    e = emission(sensor)
    azimuth, elevation = angles_deg(e.directions)
    assert np.allclose(np.abs(azimuth[e.ring == 0]), [180.0, 90.0, 0.0, 90.0], atol=1e-9)
    assert np.allclose(azimuth[e.ring == 0][1:], [90.0, 0.0, -90.0], atol=1e-9)  # behind, left, ahead, right
    assert np.allclose(elevation[:3], [-10.0, 0.0, 30.0], atol=1e-9)
    assert np.allclose(e.time, np.repeat([0.0, 0.05, 0.1, 0.15], 3))
    assert sensor.rays_per_sweep() == 12


def coverage(directions, half_h, half_v, cell_deg):
    """Fraction of the grid cells lying wholly inside the elliptical field that a ray hits."""
    az, el = angles_deg(directions)
    edges_h = np.arange(-half_h, half_h + cell_deg, cell_deg)
    edges_v = np.arange(-half_v, half_v + cell_deg, cell_deg)
    hits, _, _ = np.histogram2d(az, el, bins=[edges_h, edges_v])
    corners_h = np.maximum(np.abs(edges_h[:-1]), np.abs(edges_h[1:]))[:, None]
    corners_v = np.maximum(np.abs(edges_v[:-1]), np.abs(edges_v[1:]))[None, :]
    inside = (corners_h / half_h) ** 2 + (corners_v / half_v) ** 2 <= 1.0
    return float((hits[inside] > 0).mean())


def test_the_rosette_stays_in_its_field_fills_it_and_never_repeats():
    sensor = lidar("livox-avia")
    half_h, half_v = 70.4 / 2, 77.2 / 2
    sweeps = [emission(sensor, k) for k in range(5)]
    e = sweeps[0]
    assert len(e) == 240_000 // 10 and np.array_equal(np.bincount(e.ring), np.full(6, 4000))
    assert np.allclose(np.linalg.norm(e.directions, axis=1), 1.0, rtol=0, atol=1e-12)
    for s in sweeps:
        az, el = angles_deg(s.directions)
        assert np.abs(az).max() <= half_h + 1e-9 and np.abs(el).max() <= half_v + 1e-9
        assert ((az / half_h) ** 2 + (el / half_v) ** 2).max() <= 1.0 + 1e-9
        assert np.all(np.diff(s.time) > 0) and s.time[0] == 0.0 and s.time[-1] < 0.1
    # one 0.1 s frame covers most of a coarse grid over the field, two nearly all of it
    assert coverage(e.directions, half_h, half_v, 2.0) > 0.8
    assert coverage(np.concatenate([s.directions for s in sweeps[:2]]), half_h, half_v, 2.0) > 0.98
    one = coverage(e.directions, half_h, half_v, 0.5)
    five = coverage(np.concatenate([s.directions for s in sweeps]), half_h, half_v, 0.5)
    assert one < 0.9 and five > 0.97 and five > one + 0.1  # and finely as frames add up
    assert not np.allclose(sweeps[1].directions, e.directions, atol=1e-3)  # sweep 1 is not sweep 0 again
    # sweep 1 continues line 0 where sweep 0 left it, no jump larger than the line's own steps
    line0 = [s.directions[s.ring == 0] for s in sweeps[:2]]
    largest_step = np.linalg.norm(np.diff(line0[0], axis=0), axis=1).max()
    assert np.linalg.norm(line0[1][0] - line0[0][-1]) <= largest_step * 1.01
    assert np.linalg.norm(line0[1][0] - line0[0][0]) > 10 * largest_step


def test_the_dome_covers_every_azimuth_and_its_elevations_at_its_step():
    sensor = lidar("tls")
    e = emission(sensor)
    assert len(e) == 1800 * 751 == sensor.rays_per_sweep()
    assert np.allclose(np.linalg.norm(e.directions, axis=1), 1.0, rtol=0, atol=1e-12)
    azimuth, elevation = angles_deg(e.directions)
    assert elevation.min() >= -60.0 - 1e-9 and elevation.max() <= 90.0 + 1e-9
    rows = np.unique(np.round(elevation, 6))
    assert len(rows) == 751 and np.allclose(np.diff(rows), 0.2, atol=1e-6)
    assert np.allclose(elevation, -60.0 + 0.2 * e.ring, atol=1e-9)
    below_zenith = elevation < 89.0
    columns = np.unique(np.round(azimuth[below_zenith] % 360.0, 6))
    assert len(columns) == 1800 and np.allclose(np.diff(columns), 0.2, atol=1e-6)
    assert np.all(np.diff(e.time) > 0) and e.time[-1] < 1.0 / sensor.rate_hz


@pytest.mark.parametrize("mount", ["level", "drone"])
def test_mount_rotations_are_proper_and_the_drone_looks_down(mount):
    r = body_from_sensor(dataclasses.replace(lidar("vlp16"), mount=mount))
    assert np.allclose(r.T @ r, np.eye(3), atol=0) and np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    assert set(np.unique(r)) <= {-1.0, 0.0, 1.0}


def test_the_drone_mount_points_a_rosette_down_and_a_spinning_axis_along_the_flight_line():
    avia = lidar("livox-avia@drone")
    assert avia.name == "livox-avia@drone" and avia.mount == "drone"
    mean = body_directions(avia).mean(axis=0)
    assert mean[2] < -0.8 and np.abs(mean[:2]).max() < 0.05  # about nadir
    level = lidar("livox-avia")
    assert np.array_equal(body_directions(level), emission(level).directions)
    assert np.array_equal(emission(avia).directions, emission(level).directions)  # the sensor frame is the same
    r = body_from_sensor(lidar("vlp16@drone"))
    assert np.allclose(r @ [0, 0, 1], [1, 0, 0])  # the spin axis along the heading
    d = body_directions(lidar("vlp16@drone"))
    across = d[np.abs(d[:, 0]) < 0.3]  # beams near the plane across the flight line
    assert len(across) > 0.4 * len(d) and across[:, 2].min() < -0.99 and across[:, 1].max() > 0.99


def test_bad_names_and_parameters_give_one_line_errors():
    assert "vlp16" in one_line_error(lambda: lidar("nope"))
    assert "drone" in one_line_error(lambda: lidar("vlp16@boat"))
    assert "mount" in one_line_error(lambda: lidar("tls@drone"))
    vlp = lidar("vlp16")
    assert "range_min_m" in one_line_error(lambda: dataclasses.replace(vlp, range_min_m=200.0))
    assert "ascending" in one_line_error(lambda: dataclasses.replace(vlp, elevations_deg=(1.0, 0.0)))
    assert "rate_hz" in one_line_error(lambda: dataclasses.replace(vlp, rate_hz=0.0))
    assert "kind" in one_line_error(lambda: dataclasses.replace(vlp, kind="phased-array"))
    assert "step_deg" in one_line_error(lambda: dataclasses.replace(lidar("tls"), step_deg=0.7))
    assert "sweep_index" in one_line_error(lambda: emission(vlp, -1))


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_the_summary_is_json_and_names_every_parameter(name):
    sensor = lidar(name)
    back = json.loads(json.dumps(sensor.summary()))
    assert back["range_noise_sigma_m"] == sensor.range_noise_sigma_m > 0
    assert {f.name for f in dataclasses.fields(Lidar)} <= set(back)
    assert back["rays_per_sweep"] == len(emission(sensor))
    assert back["source"] and 0 < sensor.range_at_10pct_m <= sensor.range_max_m


def test_the_same_sensor_gives_the_same_arrays_read_only():
    for name in ("vlp16", "livox-avia"):
        first = emission(lidar(name), 3)
        patterns.cached_emission.cache_clear()
        again = emission(dataclasses.replace(lidar(name)), 3)
        assert first is not again
        for a, b in ((first.directions, again.directions), (first.ring, again.ring), (first.time, again.time)):
            assert a.tobytes() == b.tobytes() and not a.flags.writeable
    assert not math.isnan(emission(lidar("hdl64")).directions.sum())


def test_a_parameter_of_the_wrong_type_is_one_line_naming_it():
    from dataclasses import replace as swap

    base = lidar("vlp16")
    for kw, says in ((dict(range_min_m="0"), "range_min_m must be a finite number"),
                     (dict(max_incidence_deg=None), "max_incidence_deg must be a finite number"),
                     (dict(columns=True), "columns must be a whole number"),
                     (dict(rate_hz=True), "rate_hz must be a finite number"),
                     (dict(elevations_deg=["a"]), "elevations_deg must be a tuple of finite numbers"),
                     (dict(points_per_second=float("inf")), "points_per_second must be a finite number")):
        with pytest.raises(ValueError, match=says) as err:
            swap(base, **kw)
        assert "\n" not in str(err.value)
