"""What comes back from a laser beam that meets a surface (bpy-free; docs/lidar.md, "Physics").

A beam meets the first triangle of the scene along its ray (exact hits,
generator/geometry/raycast.py). With ``rho`` the surface's diffuse reflectivity at 905 nm
(the face's material: generator/scene/materials.py ``Material.lidar_reflectivity``),
``theta`` the incidence angle between the beam and the surface's normal, ``r`` the exact
range and ``tau`` the two-way transmission of the glass panes the beam passed through
(:data:`GLASS_TRANSMISSION` squared per glass face crossed):

- **intensity** = rho |cos theta| tau, in [0, 1]: a Lambertian target's reflectance as the
  sensor sees it, range-corrected (what Ouster calls reflectivity and a calibrated Velodyne
  reports); no atmospheric attenuation (clear air);
- **detection**: the received power rho |cos theta| tau / r^2 must reach that of a 10%
  target at normal incidence at the sensor's ``range_at_10pct_m`` (0.1 / R10^2); the
  incidence angle must not pass ``max_incidence_deg`` (grazing beams drop); the measured
  range must lie in [range_min_m, range_max_m] (no return past the maximum range);
- **range noise**: the measured range is r + N(0, sigma^2), sigma = ``range_noise_sigma_m``,
  from the sweep's own random stream;
- **glass**: a transparent face (clear glass) returns nothing; the beam passes through it,
  keeping :data:`GLASS_TRANSMISSION` of its power each way (a pane modelled as a thin box
  has two faces: 0.9 through the pane), and may return from what lies behind, through at
  most :data:`MAX_GLASS_FACES` faces.

Beam divergence, multiple returns and mixed pixels at edges are not modelled (one ray per
beam along its centre line).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.portable_math import cos

DEFAULT_REFLECTIVITY = 0.3  # a part without declared face reflectivities (a user's object): dull grey
GLASS_TRANSMISSION = 0.95  # one way through one face of clear glass at 905 nm (a pane's two: about 0.9)
MAX_GLASS_FACES = 8  # a beam crosses at most this many glass faces; past them it is lost


def transmission(panes: np.ndarray) -> np.ndarray:
    """tau: the two-way transmission through ``panes`` (N,) glass faces crossed (float64)."""
    tau = np.ones(len(panes))
    glazed = np.flatnonzero(panes > 0)
    for k in range(int(np.max(panes, initial=0))):
        tau[glazed] = np.where(panes[glazed] > k, tau[glazed] * (GLASS_TRANSMISSION * GLASS_TRANSMISSION), tau[glazed])
    return tau


def received(reflectivity: np.ndarray, cos_incidence: np.ndarray, range_m: np.ndarray,
             transmission: np.ndarray) -> np.ndarray:
    """rho |cos theta| tau / r^2 (relative received power, float64)."""
    return intensity(reflectivity, cos_incidence, transmission) / (range_m * range_m)


def intensity(reflectivity: np.ndarray, cos_incidence: np.ndarray, transmission: np.ndarray) -> np.ndarray:
    """rho |cos theta| tau, in [0, 1] (float64)."""
    return np.clip(np.asarray(reflectivity, np.float64) * np.abs(cos_incidence) * transmission, 0.0, 1.0)


def detected(sensor, reflectivity: np.ndarray, cos_incidence: np.ndarray, range_m: np.ndarray,
             measured_m: np.ndarray, transmission: np.ndarray) -> np.ndarray:
    """(N,) bool: the sensor reports these returns (the module's detection rules)."""
    r10 = float(sensor.range_at_10pct_m)
    threshold = 0.1 / (r10 * r10)
    cos_limit = float(cos(math.radians(sensor.max_incidence_deg)))
    strong = received(reflectivity, cos_incidence, range_m, transmission) >= threshold
    in_range = (measured_m >= sensor.range_min_m) & (measured_m <= sensor.range_max_m)
    return strong & in_range & (np.abs(cos_incidence) >= cos_limit)


def noisy(range_m: np.ndarray, sigma_m: float, draws: np.ndarray) -> np.ndarray:
    """The measured ranges: ``range_m`` + sigma ``draws`` (standard normal draws, one per beam)."""
    return np.asarray(range_m, dtype=np.float64) + sigma_m * draws
