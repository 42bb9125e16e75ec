"""Sky, light and weather per seed (generator/scene/weather.py, generator/blender/sky.py):
drawn deterministically, recorded in site.json, overridable, varied over seeds; the pixels
change, the ground truth does not; fog follows Koschmieder's law along each ray."""

import json
import math
import subprocess
import sys
from collections import Counter

import numpy as np
import pytest

from conftest import ROOT, assert_refused
from generator.scene.weather import (LATITUDE_DEG, SEASON_DAYS, SEASONS, SUN_ELEVATION_DEG, WEATHERS, WET_EXPOSURE_EV,
                                     WORKING_HOURS, choose_season, choose_weather)


def test_weather_is_drawn_per_seed_deterministically_and_an_override_keeps_the_rest():
    a, b = choose_weather(12), choose_weather(12)
    assert a == b and a.name in WEATHERS
    for name in WEATHERS:
        w = choose_weather(12, name)
        assert w.name == name and w.sun_azimuth_deg == a.sun_azimuth_deg  # the same stream, the same draws
        assert (w.fog_visibility_m is not None) == (name == "fog") and (w.wetness > 0) == (name == "after-rain")
        assert 0.0 <= w.exposure_ev <= 2.0 + (WET_EXPOSURE_EV if w.wetness else 0.0) and w.sun_strength > 0
        assert w.fog_extinction_per_m == (0.0 if name != "fog" else pytest.approx(3.912 / w.fog_visibility_m))
    wet, dry = (next(choose_weather(s, n) for s in range(50) if choose_weather(s, "after-rain").sky == "overcast")
                for n in ("after-rain", "overcast"))
    assert wet.exposure_ev == dry.exposure_ev + WET_EXPOSURE_EV  # the same light; wet ground reflects less
    with pytest.raises(ValueError, match="^unknown weather 'rainy'; choose one of clear, hazy"):
        choose_weather(12, "rainy")


def test_seeds_0_to_99_cover_four_skies_and_the_sun_from_golden_hour_to_midday():
    weathers = [choose_weather(seed) for seed in range(100)]
    skies = Counter(w.sky for w in weathers)
    assert set(skies) == {"clear", "hazy", "partly-cloudy", "overcast"} and min(skies.values()) >= 10
    assert len({w.name for w in weathers}) == len(WEATHERS)
    elevations = np.array([w.sun_elevation_deg for w in weathers])
    lo, hi = SUN_ELEVATION_DEG
    assert lo - 1e-9 <= elevations.min() < lo + 3 and 60 < elevations.max() <= hi
    assert 0.05 <= np.mean(elevations < 10) <= 0.3  # low suns are common: mornings, evenings, winters


def test_the_sun_stands_where_it_would_at_the_recorded_place_day_and_time():
    """An independent solar position (libm's asin, cos): the elevation follows from the
    recorded latitude, day and solar time; each lies in its range and the day in its season's."""
    for seed in range(60):
        w = choose_weather(seed)
        phi, hour = math.radians(w.latitude_deg), math.radians(15 * (w.solar_time_h - 12))
        dec = -math.radians(23.44) * math.cos(2 * math.pi * (w.day_of_year + 10) / 365)
        up = math.sin(phi) * math.sin(dec) + math.cos(phi) * math.cos(dec) * math.cos(hour)
        assert w.sun_elevation_deg == pytest.approx(math.degrees(math.asin(up)), abs=1e-9)
        assert LATITUDE_DEG[0] <= w.latitude_deg <= LATITUDE_DEG[1]
        assert SEASON_DAYS[w.season][0] <= w.day_of_year <= SEASON_DAYS[w.season][1]
        assert WORKING_HOURS[0] <= w.solar_time_h <= WORKING_HOURS[1] and w.sun_elevation_deg >= SUN_ELEVATION_DEG[0] - 1e-9
    # the same place and hour: the winter sun stands lower than the summer's
    for seed in range(10):
        winter, summer = choose_weather(seed, "clear", "winter"), choose_weather(seed, "clear", "summer")
        assert winter.latitude_deg == summer.latitude_deg
        noon = [90 - w.latitude_deg - 23.44 * math.cos(2 * math.pi * (w.day_of_year + 10) / 365) for w in (winter, summer)]
        assert winter.sun_elevation_deg <= noon[0] + 1e-6 < noon[1] - 10


def test_seasons_are_drawn_from_their_own_stream_and_snow_never_follows_rain():
    weathers = [choose_weather(seed) for seed in range(200)]
    seasons = Counter(w.season for w in weathers)
    assert set(seasons) == set(SEASONS) and min(seasons.values()) >= 10
    for seed, w in enumerate(weathers[:40]):
        assert (w.snow_cover > 0) == (w.season == "snow") and (w.snow_cover == 0 or 0.5 <= w.snow_cover <= 0.95)
        assert not (w.season == "snow" and w.name == "after-rain")
        for season in SEASONS:  # fixing the season moves no draw of the weather
            fixed = choose_weather(seed, season=season)
            assert fixed.latitude_deg == w.latitude_deg and fixed.name == w.name  # the sun follows the season's days
            assert fixed.season == (season if not (season == "snow" and w.name == "after-rain") else "winter")
    assert choose_season(3, "after-rain", "snow") == ("winter", 0.0)  # a thaw
    with pytest.raises(ValueError, match="^unknown season 'monsoon'; choose one of spring, summer"):
        choose_weather(1, season="monsoon")


def test_an_unknown_weather_is_one_line_and_exit_2(tmp_path):
    for module in ("generator", "generator.scene --seed 1"):
        assert_refused(subprocess.run([sys.executable, "-m", *module.split(), "--out", str(tmp_path / "x"), "--weather",
                                       "rainy"], capture_output=True, text=True, cwd=ROOT), "--weather", "after-rain")


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    """Seed 5's small site under three weathers, one view rendered at 64x48 from each:
    name -> (site, simulator, render, what the open Blender scene held: its fog and whether
    the ground's roughness is textured). One Blender file is open at a time: each is read
    before the next is built."""
    import bpy

    from generator import Simulator
    from generator.blender.season import SNOW_LABEL
    from generator.blender.sky import PUDDLES, fog_of_scene
    from generator.geometry.camera import look_at
    from generator.scene import build_site

    out = {}
    for name in ("overcast", "fog", "after-rain", "snow"):
        weather, season = ("overcast", "snow") if name == "snow" else (name, "summer")
        site = build_site(5, "small", tmp_path_factory.mktemp(name), preview=False, weather=weather, season=season)
        sim = Simulator(site.blend, points_density=0.05, seed=5, render_preset="preview")
        sim.configure_render(resolution=(64, 48))
        lo, _ = site.plan.spawn_box
        sim.set_world_from_camera(look_at(np.array([0.0, lo[1], 4.0]), np.array([0.0, 0.0, 2.0])), check_collisions=False)
        render = sim.render()
        ground = next(m for o in bpy.context.scene.objects if o.name.startswith("Ground") for m in o.data.materials)
        held = {"fog": fog_of_scene(bpy.context.scene),
                "wet": any(n.label == PUDDLES for n in ground.node_tree.nodes),
                "snow": any(n.label == SNOW_LABEL for n in ground.node_tree.nodes)}
        out[name] = (site, sim, render, held)
    return out


def test_site_json_records_the_weather_and_the_ground_truth_does_not_change(renders):
    (site_o, sim_o, o, _), (site_f, sim_f, f, _), (site_w, sim_w, w, _), (site_s, sim_s, s, _) = (
        renders[n] for n in ("overcast", "fog", "after-rain", "snow"))
    for site, name in ((site_o, "overcast"), (site_f, "fog"), (site_w, "after-rain")):
        recorded = json.loads((site.blend.parent / "site.json").read_text())
        assert recorded["weather"]["name"] == name and recorded["params"]["weather"] == name
        assert recorded["weather"]["sun_elevation_deg"] == site.plan.weather.sun_elevation_deg
    assert json.loads((site_s.blend.parent / "site.json").read_text())["weather"]["season"] == "snow"
    for other, sim in ((f, sim_f), (w, sim_w), (s, sim_s)):
        np.testing.assert_array_equal(other.depth, o.depth)
        np.testing.assert_array_equal(other.seg, o.seg)
        np.testing.assert_array_equal(other.instance, o.instance)
        np.testing.assert_array_equal(sim.point_positions, sim_o.point_positions)
        assert not np.array_equal(other.rgb, o.rgb)  # what the camera sees does change
    assert np.isfinite(o.depth).any() and np.isinf(o.depth).any()  # the view holds surfaces and sky


def test_fog_mixes_each_pixel_with_the_fog_colour_by_the_transmittance_along_its_ray(renders):
    (_, _, clear, _), (_, _, fogged, held) = renders["overcast"], renders["fog"]
    fog = held["fog"]
    assert renders["overcast"][3]["fog"] is None
    # the same sky and sun (the fog state draws the overcast state's parameters, then the fog's)
    # and the same samples: only the fog differs
    K = fogged.K
    h, w = fogged.depth.shape
    u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    ray = np.sqrt(1 + ((u - K[0, 2]) / K[0, 0]) ** 2 + ((v - K[1, 2]) / K[1, 1]) ** 2)
    distance = fogged.depth * ray  # metres along each pixel's ray
    t = np.exp(-fog["extinction_per_m"] * distance)
    expected = t[..., None] * clear.rgb_linear + (1 - t[..., None]) * np.array(fog["colour"])
    # interior pixels (the distance varies smoothly there: the Mist pass is filtered over a pixel)
    finite = np.where(np.isfinite(distance), distance, -1e9)
    same = np.isfinite(distance)
    for axis in (0, 1):
        for shift in (1, -1):
            same &= np.abs(np.roll(finite, shift, axis) - finite) < 0.05 * finite
    assert same.sum() > 200
    err = np.abs(fogged.rgb_linear - expected)[same]
    assert np.median(err) < 2e-3 and np.quantile(err, 0.95) < 0.02, (np.median(err), np.quantile(err, 0.95))
    sky = np.isinf(fogged.depth)
    np.testing.assert_allclose(fogged.rgb_linear[sky], np.broadcast_to(fog["colour"], fogged.rgb_linear[sky].shape),
                               rtol=1e-3)  # the sky is infinitely far: all fog
    assert (t[same] < 0.999).all() and (t[same] > 0.05).any()  # the test sees fog, and through it


def test_wet_ground_has_puddles_and_dry_ground_has_none(renders):
    assert renders["after-rain"][3]["wet"] and not renders["overcast"][3]["wet"]


def test_snow_whitens_level_ground_and_leaves_the_rest(renders):
    """The same view, overcast, in summer and with snow lying: level ground pixels get brighter
    (snow on about half of it or more), the sky does not change (to the denoiser's mixing)."""
    (_, _, summer, held_o), (_, _, snowy, held_s) = renders["overcast"], renders["snow"]
    assert held_s["snow"] and not held_o["snow"]
    sky = np.isinf(summer.depth)
    np.testing.assert_allclose(snowy.rgb_linear[sky].mean(axis=0), summer.rgb_linear[sky].mean(axis=0), rtol=0.05)  # the denoiser mixes neighbours
    ground = summer.seg == summer_ground_id(renders)
    assert ground.sum() > 200
    brighter = snowy.rgb_linear[ground].mean(axis=1) > summer.rgb_linear[ground].mean(axis=1) * 1.5
    assert brighter.mean() > 0.3, brighter.mean()


def summer_ground_id(renders) -> int:
    return renders["overcast"][1].label_ids["Ground"]
