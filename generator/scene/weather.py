"""Sky, light and weather of a site, chosen per seed (bpy-free): what :mod:`generator.blender.sky`
builds and site.json records (``weather``).

A seed draws one :data:`WEATHERS` state with the state's weight (``--weather NAME`` picks it
instead), then the state's parameters from their ranges, from the seed's own ``weather``
stream (no other stream moves, so the layout of a site does not depend on its weather):

- ``clear``: Hosek-Wilkie sky of low turbidity, sharp sun shadows;
- ``hazy``: the same sky with high turbidity (a whiter sky, softer and weaker sun);
- ``partly-cloudy``: the clear sky with procedural clouds covering ``cloud_cover`` of it;
- ``overcast``: the CIE overcast sky (luminance (1 + 2 sin(elevation)) / 3 of the zenith's),
  a weak, very soft sun behind the clouds;
- ``fog``: the overcast sky and fog of meteorological visibility ``fog_visibility_m``
  (extinction 3.912 / visibility per metre along each camera ray: Koschmieder's law);
- ``after-rain``: an overcast or cloudy sky and wet ground (darker, glossier, with puddles).

The sun stands where it would at a place and time (:func:`solar_elevation`): a latitude
(:data:`LATITUDE_DEG`: 35-55 degrees north, the Mediterranean to the Baltic, central China,
the United States), a day of the drawn season and a time of the working day
(:data:`WORKING_HOURS`, local solar time) while the sun is at least
:data:`SUN_MIN_ELEVATION_DEG` up: low winter suns, high summer noons, golden hours in the
morning and the evening. The azimuth stays uniform in [0, 360) (a site's orientation is
arbitrary).

A seed also draws its **season** (:data:`SEASONS`, ``--season NAME`` fixes it) from its own
``season`` stream: spring, summer, autumn and winter colour the leaves and the grass
(:mod:`generator.blender.season`), and ``snow`` is a winter with snow lying on every
upward face (``snow_cover`` of it, 0.5-0.95, in patches), except after rain (a thaw: then
it is winter without snow).
Weather changes what the cameras see, never the geometry: depth, labels, instances,
normals, flow, points, boxes and every other ground-truth output are the same whatever the
weather (docs/scenes.md, "Sky, light and weather").
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..geometry.portable_math import atan2, cos, sin
from ..geometry.seeding import stream

LATITUDE_DEG = (35.0, 55.0)  # degrees north: where the sites are
WORKING_HOURS = (6.0, 18.0)  # local solar time (12 = the sun due south)
SUN_MIN_ELEVATION_DEG = 2.0  # a site photographed by daylight: the sun at least this high
OBLIQUITY_DEG = 23.44  # the Earth's axial tilt: the sun's declination swings +-23.44 degrees over a year
# days of the year (1 = January 1st) of each season, as meteorologists count them: winter from
# December 1st (day 335) to the end of February (day 59 + 365)
SEASON_DAYS = {"spring": (60.0, 152.0), "summer": (152.0, 244.0), "autumn": (244.0, 335.0),
               "winter": (335.0, 425.0), "snow": (335.0, 425.0)}
# the bounds of the sun's elevation over all of the above (degrees)
SUN_ELEVATION_DEG = (SUN_MIN_ELEVATION_DEG, 90.0 - LATITUDE_DEG[0] + OBLIQUITY_DEG)
# name: (weight per seed, sky) -- the weights sum to 1
WEATHERS = {
    "clear": (0.25, "clear"),
    "hazy": (0.20, "hazy"),
    "partly-cloudy": (0.20, "partly-cloudy"),
    "overcast": (0.15, "overcast"),
    "fog": (0.10, "overcast"),
    "after-rain": (0.10, None),  # overcast or partly cloudy, drawn
}
# metres: fog of meteorological visibility 150-600 m (thick to light fog)
FOG_VISIBILITY_M = (150.0, 600.0)
# season: share of seeds (a year's four seasons alike; half the winters with snow lying)
SEASONS = {"spring": 0.25, "summer": 0.25, "autumn": 0.25, "winter": 0.125, "snow": 0.125}
SNOW_COVER = (0.5, 0.95)  # share of the upward faces under snow


@dataclass(frozen=True)
class Weather:
    """One site's sky, sun and weather. Angles in degrees, the sun's azimuth counter-clockwise
    from +x (east) in the site's frame; ``sun_strength``: Blender sun irradiance (W/m^2);
    ``sun_angle_deg``: the sun's angular diameter (shadow softness); ``turbidity``: Hosek-Wilkie
    haze (2 clear, 10 very hazy); ``sky_strength``: the sky's radiance scale; ``cloud_cover``:
    share of the sky covered by clouds (1 for overcast); ``fog_visibility_m``: meteorological
    visibility in metres (None: no fog); ``wetness``: 0 dry ground to 1 soaked, with puddles;
    ``exposure_ev``: the camera's exposure compensation (stops), set from the light so that
    dim scenes are exposed as a camera's automatic exposure would; ``season``: one of
    :data:`SEASONS`; ``snow_cover``: share of the upward faces under snow (0 but in the
    ``snow`` season); ``latitude_deg`` (north), ``day_of_year`` (1 = January 1st, past 365
    in a winter's January and February) and ``solar_time_h`` (local solar time, 12 = noon):
    where and when, which set ``sun_elevation_deg`` (:func:`solar_elevation`)."""

    name: str
    sky: str
    sun_elevation_deg: float
    sun_azimuth_deg: float
    sun_strength: float
    sun_angle_deg: float
    turbidity: float
    sky_strength: float
    cloud_cover: float
    fog_visibility_m: float | None
    wetness: float
    exposure_ev: float
    season: str = "summer"
    snow_cover: float = 0.0
    latitude_deg: float = 45.0
    day_of_year: float = 172.0
    solar_time_h: float = 12.0

    def summary(self) -> dict:
        """site.json's ``weather``: every field."""
        return asdict(self)

    @property
    def fog_extinction_per_m(self) -> float:
        """Extinction coefficient of the fog (1/m): 3.912 / visibility (the distance at which a
        black object keeps 2% contrast); 0 without fog."""
        return 0.0 if self.fog_visibility_m is None else 3.912 / self.fog_visibility_m


def check_weather(name: str | None) -> str | None:
    """``name`` if it names a weather state (or is None: drawn per seed); ValueError otherwise."""
    if name is not None and name not in WEATHERS:
        raise ValueError(f"unknown weather {name!r}; choose one of {', '.join(WEATHERS)}")
    return name


def check_season(name: str | None) -> str | None:
    """``name`` if it names a season (or is None: drawn per seed); ValueError otherwise."""
    if name is not None and name not in SEASONS:
        raise ValueError(f"unknown season {name!r}; choose one of {', '.join(SEASONS)}")
    return name


def choose_season(seed: int, weather: str, name: str | None = None) -> tuple[str, float]:
    """(season, snow cover) of the site of ``seed``: ``name`` or one drawn by its share from
    the seed's own ``season`` stream; snow does not lie after rain (a thaw: winter)."""
    check_season(name)
    rng = stream(seed, "season")
    names = list(SEASONS)
    drawn = names[int(rng.choice(len(names), p=[SEASONS[n] for n in names]))]
    cover = float(rng.uniform(*SNOW_COVER))  # drawn for every season: the same draws follow
    season = name or drawn
    if season == "snow" and weather == "after-rain":
        season = "winter"
    return season, cover if season == "snow" else 0.0


def choose_weather(seed: int, name: str | None = None, season: str | None = None) -> Weather:
    """The weather of the site of ``seed``: the state ``name``, or one drawn by its weight,
    with its parameters drawn from the seed's ``weather`` stream, and its season
    (:func:`choose_season`; ``season`` fixes it, and the day of the year with it)."""
    check_weather(name)
    rng = stream(seed, "weather")
    names = list(WEATHERS)
    drawn = names[int(rng.choice(len(names), p=[WEATHERS[n][0] for n in names]))]
    name = name or drawn
    rain_sky = "overcast" if rng.uniform() < 0.6 else "partly-cloudy"  # drawn for every state: the same draws follow
    sky = WEATHERS[name][1] or rain_sky
    seasonal, snow = choose_season(seed, name, season)
    latitude = float(rng.uniform(*LATITUDE_DEG))
    first, last = SEASON_DAYS[seasonal]
    day = first + float(rng.uniform()) * (last - first)
    start, end = sunlit_hours(latitude, day)
    time = start + float(rng.uniform()) * (end - start)
    elevation = solar_elevation(latitude, day, time)
    azimuth = float(rng.uniform(0.0, 360.0))
    turbidity = float(rng.uniform(5.0, 9.0) if sky == "hazy" else rng.uniform(2.0, 3.5))
    cover = {"clear": 0.0, "hazy": 0.0, "partly-cloudy": float(rng.uniform(0.3, 0.6)), "overcast": 1.0}[sky]
    sun = float(rng.uniform(2.5, 4.5)) * {"clear": 1.0, "hazy": 0.7, "partly-cloudy": 1.0, "overcast": 0.08}[sky]
    sun_angle = float(rng.uniform(15.0, 30.0) if sky == "overcast" else rng.uniform(0.5, 3.0))
    sky_strength = float(rng.uniform(3.0, 5.0))
    fog = float(rng.uniform(*FOG_VISIBILITY_M)) if name == "fog" else None
    wet = float(rng.uniform(0.6, 1.0)) if name == "after-rain" else 0.0
    return Weather(name, sky, elevation, azimuth, sun, sun_angle, turbidity, sky_strength, cover, fog, wet,
                   exposure_for(sky, elevation, sun) + (WET_EXPOSURE_EV if wet else 0.0), seasonal, snow,
                   latitude, day, time)


def sun_declination(day: float) -> float:
    """The sun's declination (radians) on ``day`` of the year: -23.44 degrees x
    cos(2 pi (day + 10) / 365) (lowest at the December solstice, about day 355)."""
    return -math.radians(OBLIQUITY_DEG) * float(cos(2.0 * math.pi * (day + 10.0) / 365.0))


def _asin(x: float) -> float:
    """arcsin x (radians) from the portable atan2."""
    return float(atan2(x, float(np.sqrt(max(0.0, 1.0 - x * x)))))


def solar_elevation(latitude_deg: float, day: float, solar_time_h: float) -> float:
    """The sun's elevation above the horizon (degrees) at ``latitude_deg`` north on ``day`` of
    the year at local solar time ``solar_time_h``: sin(elevation) = sin(latitude) sin(declination)
    + cos(latitude) cos(declination) cos(hour angle), the hour angle 15 degrees per hour from
    noon (no refraction, no equation of time: solar, not clock, time)."""
    phi, dec = math.radians(latitude_deg), sun_declination(day)
    hour = math.radians(15.0 * (solar_time_h - 12.0))
    s = float(sin(phi)) * float(sin(dec)) + float(cos(phi)) * float(cos(dec)) * float(cos(hour))
    return math.degrees(_asin(s))


def sunlit_hours(latitude_deg: float, day: float) -> tuple[float, float]:
    """The local solar times (hours) between which the sun stands at least
    :data:`SUN_MIN_ELEVATION_DEG` up on ``day`` at ``latitude_deg``, within
    :data:`WORKING_HOURS`."""
    phi, dec = math.radians(latitude_deg), sun_declination(day)
    c = (float(sin(math.radians(SUN_MIN_ELEVATION_DEG))) - float(sin(phi)) * float(sin(dec))) / (
        float(cos(phi)) * float(cos(dec)))
    c = min(1.0, max(-1.0, c))
    half = math.degrees(float(atan2(float(np.sqrt(1.0 - c * c)), c))) / 15.0  # hours from noon to the sun at the minimum
    return max(WORKING_HOURS[0], 12.0 - half), min(WORKING_HOURS[1], 12.0 + half)


WET_EXPOSURE_EV = 2.0 / 3.0  # wet ground reflects about half the light: automatic exposure opens up 2/3 stop more


def exposure_for(sky: str, elevation_deg: float, sun_strength: float) -> float:
    """Exposure compensation in stops, in a camera's third-stop steps: its automatic exposure,
    approximated from the horizontal irradiance of the sun (``sun_strength`` x sin(elevation))
    next to that of a reference sun of 3.5 at 45 degrees, both with the sky's share: the most
    k/3 stops with 2^(k/3) <= the ratio (compared as ratio^3 >= 2^k: no logarithm, so the same
    on every CPU), 0 to +2 stops. Overcast skies get +1 stop on top (their light comes from
    the sky, not the sun)."""
    direct = sun_strength * float(sin(math.radians(elevation_deg)))
    reference = 3.5 * float(sin(math.radians(45.0)))
    ambient = 0.6 * reference  # the sky's share of a reference scene's light
    ratio = (reference + ambient) / (direct + ambient)
    thirds = 3 if sky == "overcast" else 0
    for k in range(6, 0, -1):
        if ratio * ratio * ratio >= float(1 << k):
            thirds += k
            break
    return min(thirds, 6) / 3.0
