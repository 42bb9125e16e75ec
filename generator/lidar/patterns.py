"""Where a LiDAR's beams go, and when (bpy-free): the emission pattern of each kind of sensor
and the mounts that carry one (generator/lidar/sensors.py declares the sensors).

Frames. The **sensor frame** is KITTI's Velodyne frame: x forward, y left, z up, origin at the
optical centre. Azimuth is measured counter-clockwise from +x seen from above (+y is at 90
degrees), elevation up from the xy plane; a beam at (elevation el, azimuth az) points along
(cos el cos az, cos el sin az, sin el). The **body frame** is the carrier's (a car, a
tripod, a drone): x forward (its heading), y left, z up, level. ``body_from_sensor`` (3x3,
entries 0 and +-1) turns sensor-frame directions into body-frame ones:

- ``"level"``: the identity (the sensor sits upright, looking along the heading);
- ``"drone"``: pitched 90 degrees nose-down under a drone: the sensor's +x points straight
  down (nadir) and its +z along the drone's heading, its y stays the drone's y. A rosette
  then looks at the ground below; a spinning head's spin axis lies along the flight line,
  so it sweeps the vertical plane across it, the seam (sensor -x) pointing up into the drone.

:func:`emission` gives one sweep's beams in the **sensor frame** (the mount is not applied:
the scanner composes the body's pose with ``body_from_sensor`` and fires these directions
from there; :func:`body_directions` gives them in the body frame). Kinds:

- **spinning** (Velodyne, Ouster): ``columns`` firings per revolution; all beams of a column
  fire together at ``c / (columns rate_hz)`` (per-laser firing offsets of a few microseconds
  are not modelled). The head turns clockwise seen from above, as Velodyne's and Ouster's
  do: the sweep starts and ends behind the sensor (azimuth 180 degrees, KITTI's seam), column
  c at azimuth ``180 - c 360 / columns`` degrees. Rays in column order, beams in ring order.
- **rosette** (Livox): a non-repetitive rosette, as two counter-rotating Risley prisms make.
  Livox publishes no formula; ours: point ``g`` (counted from sweep 0's first point, so a
  sweep continues where the last one stopped) of line ``l`` is the unit-disk point
  ``p = (e^{i a} + e^{i b}) / 2`` with ``a = 2 pi (f1 g / pps + l / lines)`` and
  ``b = 2 pi (-f2 g / pps + l / lines)`` (``f1, f2 = prism_hz``, ``pps = points_per_second``),
  i.e. the same rosette turned by ``l 360 / lines`` degrees for line ``l``; ``p`` scaled to
  the field of view gives azimuth ``Re p fov_horizontal / 2`` and elevation ``Im p
  fov_vertical / 2``: an elliptical field, densest at its centre (every petal crosses it).
  With f1/f2 irrational the pattern never repeats, and the field fills in as sweeps add up.
  Points fire one after the other at ``1 / pps``, lines in turn (point i: line ``i % lines``).
- **dome** (a terrestrial scanner on a tripod): the head turns once over the scan, clockwise
  from behind as above, at ``step_deg`` per column (``360 / step_deg`` columns); each column is
  a vertical profile from ``elevation_min_deg`` (the tripod's blind cone below) up to
  ``elevation_max_deg`` at ``step_deg``, fired bottom to top, every ray at its own time
  (uniform over ``1 / rate_hz``). The zenith, if reached, is in every column (a real
  scanner's profile crosses it too).

``ring`` is the beam's index: spinning, the beam (0: the lowest); rosette, the line; dome,
the profile's row (0: the lowest). Everything here is float64 IEEE arithmetic with the
project's portable sine and cosine (generator/geometry/portable_math.py): the same bits on
every CPU.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..geometry.camera import rows_times
from ..geometry.portable_math import sincos

RADIANS_PER_DEGREE = np.pi / 180.0
TURN = 2.0 * np.pi
WHOLE = 1e-6  # a count given as a ratio (360 / step, points per sweep) must be this close to a whole number


@dataclass(frozen=True)
class Emission:
    """One sweep's beams, in firing order."""

    directions: np.ndarray  # (N, 3) float64 unit vectors, sensor frame (x forward, y left, z up)
    ring: np.ndarray  # (N,) uint16 beam index (see the module's docstring)
    time: np.ndarray  # (N,) float64 seconds after the sweep's start, non-decreasing, in [0, 1 / rate_hz)
    firing_times: np.ndarray  # (K,) float64 the distinct values of ``time``, increasing
    firing: np.ndarray  # (N,) int64 each beam's index into ``firing_times`` (beams fired together share it)

    def __len__(self) -> int:
        return len(self.time)


def whole(ratio: float, what: str) -> int:
    """``ratio`` as an int, or a ValueError naming ``what`` when it is not a whole number."""
    n = int(round(ratio))
    if n < 1 or abs(ratio - n) > WHOLE:
        raise ValueError(f"{what} is {ratio:g}, not a whole number of at least 1: change the parameters so it is")
    return n


def unit_directions(elevation_rad: np.ndarray, azimuth_rad: np.ndarray) -> np.ndarray:
    """(N, 3) (cos el cos az, cos el sin az, sin el) of N (elevation, azimuth) pairs in radians."""
    sin_el, cos_el = sincos(np.asarray(elevation_rad, dtype=np.float64))
    sin_az, cos_az = sincos(np.asarray(azimuth_rad, dtype=np.float64))
    return np.stack([cos_el * cos_az, cos_el * sin_az, sin_el], axis=-1)


def clockwise_from_behind_deg(columns: int) -> np.ndarray:
    """Azimuths (degrees, counter-clockwise from +x) of ``columns`` equal steps of a head turning
    clockwise seen from above, starting behind the sensor: 180, 180 - 360/columns, ..."""
    return 180.0 - np.arange(columns, dtype=np.float64) * (360.0 / columns)


# --- spinning -------------------------------------------------------------------------------

def check_spinning(s) -> None:
    el = np.asarray(s.elevations_deg, dtype=np.float64)
    if el.size == 0 or el.size > 65535:
        raise ValueError(f"sensor {s.name!r}: a spinning sensor needs 1 to 65535 beam elevations, got {el.size}")
    if not np.all(np.isfinite(el)) or np.any(np.abs(el) >= 90.0) or np.any(np.diff(el) <= 0.0):
        raise ValueError(f"sensor {s.name!r}: elevations_deg must be finite, within (-90, 90) and strictly "
                         f"ascending (ring 0 = the lowest beam)")
    if not isinstance(s.columns, int) or s.columns < 1:
        raise ValueError(f"sensor {s.name!r}: columns (firings per revolution) must be a positive int, "
                         f"got {s.columns!r}")


def count_spinning(s) -> int:
    return len(s.elevations_deg) * s.columns


def emit_spinning(s, sweep_index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column after column, each column's beams in ring order (``sweep_index`` is ignored)."""
    beams, columns = len(s.elevations_deg), s.columns
    azimuth = clockwise_from_behind_deg(columns) * RADIANS_PER_DEGREE
    elevation = np.asarray(s.elevations_deg, dtype=np.float64) * RADIANS_PER_DEGREE
    directions = unit_directions(np.tile(elevation, columns), np.repeat(azimuth, beams))
    ring = np.tile(np.arange(beams, dtype=np.uint16), columns)
    time = np.repeat(np.arange(columns, dtype=np.float64) / (columns * s.rate_hz), beams)
    return directions, ring, time


# --- rosette --------------------------------------------------------------------------------

def check_rosette(s) -> None:
    for name in ("fov_horizontal_deg", "fov_vertical_deg"):
        if not 0.0 < getattr(s, name) < 180.0:
            raise ValueError(f"sensor {s.name!r}: {name} must lie in (0, 180) degrees, got {getattr(s, name)!r}")
    if not isinstance(s.lines, int) or not 1 <= s.lines <= 65535:
        raise ValueError(f"sensor {s.name!r}: lines must be an int in [1, 65535], got {s.lines!r}")
    if len(s.prism_hz) != 2 or not (s.prism_hz[0] > 0.0 and s.prism_hz[1] > 0.0 and s.prism_hz[0] != s.prism_hz[1]):
        raise ValueError(f"sensor {s.name!r}: prism_hz must be two different positive frequencies, got {s.prism_hz!r}")
    if not s.points_per_second > 0:
        raise ValueError(f"sensor {s.name!r}: points_per_second must be positive, got {s.points_per_second!r}")
    whole(s.points_per_second / s.rate_hz, f"sensor {s.name!r}: points per sweep (points_per_second / rate_hz)")


def count_rosette(s) -> int:
    return whole(s.points_per_second / s.rate_hz, "points per sweep")


def emit_rosette(s, sweep_index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sweep ``sweep_index`` of the rosette: it continues the pattern where sweep - 1 stopped."""
    n = count_rosette(s)
    i = np.arange(n, dtype=np.int64)
    number = i + np.int64(sweep_index) * n  # the point's number since sweep 0
    g = number.astype(np.float64)
    line = (number % s.lines).astype(np.float64) / s.lines  # each line's rosette turned by a 1/lines turn
    f1, f2 = s.prism_hz
    sin_a, cos_a = sincos(np.mod(g * (f1 / s.points_per_second) + line, 1.0) * TURN)
    sin_b, cos_b = sincos(np.mod(line - g * (f2 / s.points_per_second), 1.0) * TURN)
    u = np.clip((cos_a + cos_b) * 0.5, -1.0, 1.0)
    v = np.clip((sin_a + sin_b) * 0.5, -1.0, 1.0)
    azimuth = u * (s.fov_horizontal_deg * 0.5 * RADIANS_PER_DEGREE)
    elevation = v * (s.fov_vertical_deg * 0.5 * RADIANS_PER_DEGREE)
    time = i.astype(np.float64) / s.points_per_second
    return unit_directions(elevation, azimuth), (number % s.lines).astype(np.uint16), time


# --- dome -----------------------------------------------------------------------------------

def dome_shape(s) -> tuple[int, int]:
    """(columns, rows) of a dome scan."""
    columns = whole(360.0 / s.step_deg, f"sensor {s.name!r}: 360 / step_deg")
    rows = whole((s.elevation_max_deg - s.elevation_min_deg) / s.step_deg,
                 f"sensor {s.name!r}: (elevation_max_deg - elevation_min_deg) / step_deg") + 1
    return columns, rows


def check_dome(s) -> None:
    if not 0.0 < s.step_deg <= 90.0:
        raise ValueError(f"sensor {s.name!r}: step_deg must lie in (0, 90] degrees, got {s.step_deg!r}")
    if not -90.0 <= s.elevation_min_deg < s.elevation_max_deg <= 90.0:
        raise ValueError(f"sensor {s.name!r}: need -90 <= elevation_min_deg < elevation_max_deg <= 90, got "
                         f"{s.elevation_min_deg!r} and {s.elevation_max_deg!r}")
    if dome_shape(s)[1] > 65536:
        raise ValueError(f"sensor {s.name!r}: more than 65536 rows per profile: use a coarser step_deg")


def count_dome(s) -> int:
    columns, rows = dome_shape(s)
    return columns * rows


def emit_dome(s, sweep_index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Profile after profile, each from the lowest row up (``sweep_index`` is ignored)."""
    columns, rows = dome_shape(s)
    azimuth = clockwise_from_behind_deg(columns) * RADIANS_PER_DEGREE
    rows_deg = np.minimum(s.elevation_min_deg + np.arange(rows, dtype=np.float64) * s.step_deg, s.elevation_max_deg)
    elevation = rows_deg * RADIANS_PER_DEGREE
    directions = unit_directions(np.tile(elevation, columns), np.repeat(azimuth, rows))
    ring = np.tile(np.arange(rows, dtype=np.uint16), columns)
    time = np.arange(columns * rows, dtype=np.float64) / (columns * rows * s.rate_hz)
    return directions, ring, time


# --- the registries -------------------------------------------------------------------------

@dataclass(frozen=True)
class Kind:
    """A kind of sensor: how its parameters are checked, how many rays a sweep has, its
    pattern, whether the pattern changes from sweep to sweep, and the mounts that suit it."""

    check: Callable[[object], None]
    count: Callable[[object], int]
    emit: Callable[[object, int], tuple[np.ndarray, np.ndarray, np.ndarray]]
    per_sweep: bool
    mounts: tuple[str, ...]


KINDS: dict[str, Kind] = {
    "spinning": Kind(check_spinning, count_spinning, emit_spinning, False, ("level", "drone")),
    "rosette": Kind(check_rosette, count_rosette, emit_rosette, True, ("level", "drone")),
    "dome": Kind(check_dome, count_dome, emit_dome, False, ("level",)),  # a tripod scanner
}

# body_from_sensor of each mount: columns are the sensor's x, y, z axes in the body frame
MOUNTS: dict[str, tuple[tuple[int, int, int], ...]] = {
    "level": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "drone": ((0, 0, 1), (0, 1, 0), (-1, 0, 0)),  # sensor x -> body -z (nadir), sensor z -> body x
}


def body_from_sensor(sensor) -> np.ndarray:
    """The sensor's mount rotation (3x3 float64, read-only, entries 0 and +-1): body-frame
    vector = body_from_sensor @ sensor-frame vector."""
    out = np.array(MOUNTS[sensor.mount], dtype=np.float64)
    out.setflags(write=False)
    return out


def emission(sensor, sweep_index: int = 0) -> Emission:
    """Sweep number ``sweep_index`` (from 0) of ``sensor``'s beams, in the sensor frame (read-only
    arrays, cached: the same sensor gives the same arrays). Spinning and dome sensors repeat
    the same pattern every sweep; a rosette continues it."""
    if isinstance(sweep_index, bool) or not isinstance(sweep_index, (int, np.integer)) or sweep_index < 0:
        raise ValueError(f"sweep_index must be an int >= 0, got {sweep_index!r}")
    return cached_emission(sensor, int(sweep_index) if KINDS[sensor.kind].per_sweep else 0)


@functools.lru_cache(maxsize=8)
def cached_emission(sensor, sweep_index: int) -> Emission:
    directions, ring, time = KINDS[sensor.kind].emit(sensor, sweep_index)
    firing_times, firing = np.unique(time, return_inverse=True)
    arrays = (directions, ring, time, firing_times, firing.astype(np.int64))
    for a in arrays:
        a.setflags(write=False)
    return Emission(*arrays)


def body_directions(sensor, sweep_index: int = 0) -> np.ndarray:
    """(N, 3) float64: :func:`emission`'s directions turned into the body frame by the mount."""
    return rows_times(emission(sensor, sweep_index).directions, body_from_sensor(sensor).T)
