"""A LiDAR sensor declared once (bpy-free; docs/lidar.md, "Sensors"): :class:`Lidar` holds its
named parameters, :data:`PRESETS` the makers' sensors (each with the data sheet it follows and
what was assumed where the sheet is silent), :func:`lidar` looks one up by name.

A user builds a variant with ``dataclasses.replace(lidar("vlp16"), range_noise_sigma_m=0.0)``
or a new sensor with ``Lidar(...)``; either is checked on creation (a one-line ValueError).
Where the beams go and when is :func:`emission` (generator/lidar/patterns.py: the kinds
``spinning``, ``rosette`` and ``dome``, the frames, and the mounts ``level`` and ``drone``);
what a beam brings back is generator/lidar/physics.py, which reads ``range_at_10pct_m``,
``max_incidence_deg``, ``range_min_m``, ``range_max_m`` and ``range_noise_sigma_m``.

Units are in the names: metres, degrees, hertz, milliradians, seconds.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from .patterns import KINDS, MOUNTS, Emission, body_directions, body_from_sensor, emission

__all__ = ["Lidar", "PRESETS", "lidar", "emission", "Emission", "body_from_sensor", "body_directions"]


@dataclass(frozen=True)
class Lidar:
    """A laser scanner. Parameters a kind does not use keep their defaults (empty, 0)."""

    name: str  # a preset's name, or the user's; it seeds the sweep's noise stream
    kind: str  # "spinning" | "rosette" | "dome" (generator/lidar/patterns.py)
    source: str  # the data sheet or manual it follows, and what was assumed where it is silent
    rate_hz: float  # sweeps per second: a revolution, a rosette frame, or a whole dome scan (1 / its duration)
    range_min_m: float  # nearer returns are not reported
    range_max_m: float  # farther returns are not reported
    range_noise_sigma_m: float  # 1-sigma Gaussian noise added to each measured range
    range_at_10pct_m: float  # a 10%-reflective Lambertian target at normal incidence is detected up to here
    max_incidence_deg: float = 85.0  # returns at a larger angle between beam and surface normal drop
    beam_divergence_mrad: float = 0.0  # documentation only: one ray per beam, along its centre line
    # spinning: each beam's elevation, ring order (ring 0 = the lowest beam, ascending), and
    # firings per revolution (azimuth step 360 / columns degrees)
    elevations_deg: tuple[float, ...] = ()
    columns: int = 0
    # rosette: the field of view around +x (full angles), the point rate over all lines, the
    # number of lines (laser emitters), and the two prisms' turns per second
    fov_horizontal_deg: float = 0.0
    fov_vertical_deg: float = 0.0
    points_per_second: float = 0.0
    lines: int = 1
    prism_hz: tuple[float, float] = (0.0, 0.0)
    # dome: the angular step in azimuth and elevation, and the profile's vertical limits
    step_deg: float = 0.0
    elevation_min_deg: float = -90.0
    elevation_max_deg: float = 90.0
    mount: str = "level"  # "level" | "drone" (generator/lidar/patterns.py: body_from_sensor)

    def __post_init__(self):
        check_types(self)
        object.__setattr__(self, "elevations_deg", tuple(float(e) for e in self.elevations_deg))
        object.__setattr__(self, "prism_hz", tuple(float(f) for f in self.prism_hz))
        check_common(self)
        KINDS[self.kind].check(self)

    def rays_per_sweep(self) -> int:
        """The number of beams one sweep fires."""
        return KINDS[self.kind].count(self)

    def summary(self) -> dict:
        """Every parameter, JSON-ready (written to lidar.json), with the rays per sweep and the
        mount's rotation (``body_from_sensor``, rows)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["elevations_deg"] = list(self.elevations_deg)
        out["prism_hz"] = list(self.prism_hz)
        out["rays_per_sweep"] = self.rays_per_sweep()
        out["body_from_sensor"] = [list(row) for row in body_from_sensor(self).tolist()]
        return out


def _number(value) -> bool:
    """A finite real number (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def check_types(s: Lidar) -> None:
    """Each parameter of the type it is declared with: a finite number where a float is, a
    whole number where an int is, numbers in the tuples (a one-line ValueError naming it)."""
    for f in dataclasses.fields(s):
        value = getattr(s, f.name)
        if f.type == "float" and not _number(value):
            raise ValueError(f"sensor {s.name!r}: {f.name} must be a finite number, got {value!r}")
        if f.type == "int" and not (isinstance(value, int) and not isinstance(value, bool)):
            raise ValueError(f"sensor {s.name!r}: {f.name} must be a whole number, got {value!r}")
        if f.type.startswith("tuple[float") and not (isinstance(value, (tuple, list)) and all(map(_number, value))):
            raise ValueError(f"sensor {s.name!r}: {f.name} must be a tuple of finite numbers, got {value!r}")


def check_common(s: Lidar) -> None:
    """The checks every kind shares (a one-line ValueError naming the parameter)."""
    if not isinstance(s.name, str) or not s.name:
        raise ValueError(f"a Lidar needs a non-empty name, got {s.name!r}")
    if s.kind not in KINDS:
        raise ValueError(f"sensor {s.name!r}: kind {s.kind!r} is unknown; choose one of {sorted(KINDS)}")
    if s.mount not in KINDS[s.kind].mounts:
        raise ValueError(f"sensor {s.name!r}: mount {s.mount!r} does not suit a {s.kind} sensor; "
                         f"choose one of {list(KINDS[s.kind].mounts)}")
    numbers = {"rate_hz": s.rate_hz, "range_max_m": s.range_max_m, "range_at_10pct_m": s.range_at_10pct_m}
    for name, value in numbers.items():
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f"sensor {s.name!r}: {name} must be a positive number, got {value!r}")
    if not 0.0 <= s.range_min_m < s.range_max_m:
        raise ValueError(f"sensor {s.name!r}: need 0 <= range_min_m < range_max_m, got {s.range_min_m!r} "
                         f"and {s.range_max_m!r}")
    for name in ("range_noise_sigma_m", "beam_divergence_mrad"):
        value = getattr(s, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise ValueError(f"sensor {s.name!r}: {name} must be a number >= 0, got {value!r}")
    if not 0.0 < s.max_incidence_deg <= 90.0:
        raise ValueError(f"sensor {s.name!r}: max_incidence_deg must lie in (0, 90], got {s.max_incidence_deg!r}")


def block(start_deg: float, step_deg: float, count: int) -> tuple[float, ...]:
    """``count`` elevations from ``start_deg`` in steps of ``step_deg`` (negative: downwards)."""
    return tuple(start_deg + k * step_deg for k in range(count))


PRESETS: dict[str, Lidar] = {p.name: p for p in (
    Lidar(
        name="vlp16", kind="spinning",
        source="Velodyne VLP-16 (Puck) User Manual 63-9243 Rev. D (2018) and data sheet: 16 lasers at -15 to "
               "+15 deg in 2 deg steps (Table 9-1; our ring order is by elevation, not Velodyne's laser id), "
               "0.1-0.4 deg azimuth at 5-20 Hz (0.2 deg at 10 Hz: 1800 columns), range up to 100 m, accuracy "
               "+-3 cm typical, beam divergence about 3 mrad. Assumed: sigma 1.5 cm (the +-3 cm read as a "
               "two-sigma band); 10% range 35 m (the 100 m read as for a bright ~80% target, scaled by the "
               "1/r^2 law: 100 sqrt(0.1/0.8)); minimum range 0.5 m.",
        rate_hz=10.0, range_min_m=0.5, range_max_m=100.0, range_noise_sigma_m=0.015, range_at_10pct_m=35.0,
        beam_divergence_mrad=3.0, elevations_deg=block(-15.0, 2.0, 16), columns=1800),
    Lidar(
        name="hdl64", kind="spinning",
        source="Velodyne HDL-64E S2 data sheet and HDL-64E S3 User's Manual (63-HDL64ES3 Rev K, 2019): 64 "
               "lasers in an upper and a lower block of 32, vertical field +2 to about -24.8 deg, 5-15 Hz, "
               "over 1.333 M points/s, range 50 m for pavement (~10%) and 120 m for cars and foliage (~80%), "
               "accuracy < 2 cm (1 sigma). Each unit's exact angles are in its calibration file (db.xml); we "
               "use the nominal blocks: upper +2 deg down to -8.33 in 1/3 deg steps, lower -8.83 down to "
               "-24.33 in 1/2 deg steps. 2083 columns: 1.333 M points/s / 64 lasers / 10 Hz (0.1728 deg, "
               "the firing rate of the sheet). Assumed: minimum range 0.9 m; beam divergence about 2 mrad.",
        rate_hz=10.0, range_min_m=0.9, range_max_m=120.0, range_noise_sigma_m=0.02, range_at_10pct_m=50.0,
        beam_divergence_mrad=2.0, columns=2083,
        elevations_deg=sorted(block(2.0, -1.0 / 3.0, 32) + block(-8.83, -0.5, 32))),
    Lidar(
        name="os1-128", kind="spinning",
        source="Ouster OS1 data sheet (128-channel; e.g. scribd.com/document/672435817/Ouster-OS1-Datasheet): "
               "128 beams over +22.5 to -22.5 deg (taken uniformly spaced: each unit's calibrated beam "
               "angles differ slightly; per-beam azimuth offsets are not modelled), 2048 columns at 10 Hz, "
               "range 0.8-120 m for an 80% and 0.8-40 m for a 10% Lambertian target (100 klx sunlight), "
               "range repeatability (1 sigma) +-1.5 cm at SNR > 250, +-3 cm at SNR 100, +-10 cm at SNR 12: "
               "we take 3 cm; beam divergence 0.18 deg FWHM (3.1 mrad).",
        rate_hz=10.0, range_min_m=0.8, range_max_m=120.0, range_noise_sigma_m=0.03, range_at_10pct_m=40.0,
        beam_divergence_mrad=3.1, columns=2048, elevations_deg=block(-22.5, 45.0 / 127.0, 128)),
    Lidar(
        name="livox-avia", kind="rosette",
        source="Livox Avia User Manual v1.0 (2020.10) specifications and the Livox SDK (livox_ros_driver "
               "lds.h: Avia 240,000 points/s, 6 laser lines): non-repetitive (circular) scanning over "
               "70.4 x 77.2 deg, 240,000 points/s (first return), 10 Hz frames, detection range 190 m at "
               "10% and 320 m at 80% reflectivity (100 klx), range precision 2 cm (1 sigma at 20 m), beam "
               "divergence 0.28 x 0.03 deg (4.9 x 0.5 mrad). Livox publishes neither the rosette's formula "
               "nor its prisms' speeds: the pattern (generator/lidar/patterns.py) and prism_hz are ours. "
               "Assumed: minimum range 1 m.",
        rate_hz=10.0, range_min_m=1.0, range_max_m=320.0, range_noise_sigma_m=0.02, range_at_10pct_m=190.0,
        beam_divergence_mrad=4.9, fov_horizontal_deg=70.4, fov_vertical_deg=77.2, points_per_second=240_000.0,
        lines=6, prism_hz=(121.57, 77.73)),
    Lidar(
        name="tls", kind="dome",
        source="A terrestrial laser scanner of the Leica RTC360 class (its data sheet; Faro Focus alike): "
               "range 0.5-130 m, range noise 0.4 mm at 10 m and 0.5 mm at 20 m, field of view 360 x 300 deg "
               "(the tripod's blind cone below -60 deg), up to 2 M points/s. Assumed: sigma 1 mm (longer "
               "ranges, darker surfaces); 10% range 46 m (the 130 m read as for a bright ~80% target: "
               "130 sqrt(0.1/0.8)); a 0.2 deg step (35 mm at 10 m, far coarser than the scanner's 3-12 mm, "
               "to keep a scan to 1800 x 751 = 1,351,800 rays); a dome in 30 s; beam divergence about 0.5 "
               "mrad. Such scanners work at 1550 nm, where reflectivities differ from the 905 nm ones used.",
        rate_hz=1.0 / 30.0, range_min_m=0.5, range_max_m=130.0, range_noise_sigma_m=0.001, range_at_10pct_m=46.0,
        beam_divergence_mrad=0.5, step_deg=0.2, elevation_min_deg=-60.0, elevation_max_deg=90.0),
)}


def lidar(name: str) -> Lidar:
    """The preset ``name`` (:data:`PRESETS`), optionally carried by a mount: ``"NAME@MOUNT"``
    (e.g. ``"vlp16@drone"``: its name becomes that string); a ValueError names the choices."""
    base, _, mount = str(name).partition("@")
    if base not in PRESETS or (mount and mount not in MOUNTS):
        raise ValueError(f"unknown LiDAR {name!r}: choose one of {sorted(PRESETS)}, optionally with a mount "
                         f"suffix @{'/@'.join(sorted(MOUNTS))} (e.g. 'vlp16@drone')")
    if not mount:
        return PRESETS[base]
    return dataclasses.replace(PRESETS[base], name=f"{base}@{mount}", mount=mount)
