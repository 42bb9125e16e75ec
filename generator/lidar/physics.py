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
  from the sweep's own random stream (one standard normal per beam that met a surface, in
  beam order);
- **glass**: a transparent face (clear glass) returns nothing; the beam passes through it,
  keeping :data:`GLASS_TRANSMISSION` of its power each way (a pane modelled as a thin box
  has two faces: 0.9 through the pane), and may return from what lies behind, through at
  most :data:`MAX_GLASS_FACES` faces.

Beam divergence, multiple returns and mixed pixels at edges are not modelled (one ray per
beam along its centre line).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..geometry.portable_math import cos

DEFAULT_REFLECTIVITY = 0.3  # a part without declared face reflectivities (a user's object): dull grey
GLASS_TRANSMISSION = 0.95  # one way through one face of clear glass at 905 nm (a pane's two: about 0.9)
MAX_GLASS_FACES = 8  # a beam crosses at most this many glass faces; past them it is lost


@numba.njit(cache=True, nogil=True)
def returns(part: np.ndarray, face: np.ndarray, first_face: np.ndarray, reflectivity: np.ndarray,
            normal: np.ndarray, direction: np.ndarray, panes: np.ndarray, range_m: np.ndarray, draws: np.ndarray,
            rules: np.ndarray, rows: np.ndarray, measured: np.ndarray, exact: np.ndarray,
            intensity: np.ndarray) -> int:
    """The module's rules for every beam i (its hit: ``part[i]`` (-1: none), ``face[i]``,
    unit ``normal[i]`` (float32), ``range_m[i]``, glass faces crossed ``panes[i]``; its world
    ``direction[i]``; the k-th beam that met a surface, in beam order, has the standard normal
    ``draws[k]``): writes the reported returns, in beam
    order, as rows (their beams), measured and exact ranges (float64) and intensity
    (float32), and returns their count. ``reflectivity`` is every part's faces' rho, part p's
    face f at ``first_face[p] + f``; ``rules`` = (sigma, detection threshold on the received
    power (0.1 / R10^2), cos of the largest incidence angle, minimum range, maximum range).
    Intensity = (rho |cos theta|) tau clipped to [0, 1], received = intensity / r^2,
    tau = (GLASS_TRANSMISSION^2)^panes by repeated products, |cos theta| = |(n0 d0 + n1 d1) +
    n2 d2|: float64, in this order (numba keeps it: tests/test_visibility.py)."""
    sigma, threshold, cos_limit, range_min, range_max = rules[0], rules[1], rules[2], rules[3], rules[4]
    two_way = GLASS_TRANSMISSION * GLASS_TRANSMISSION
    m, k = 0, 0
    for i in range(part.shape[0]):
        p = part[i]
        if p < 0:
            continue
        draw = draws[k]
        k += 1
        cos_i = abs((np.float64(normal[i, 0]) * direction[i, 0] + np.float64(normal[i, 1]) * direction[i, 1])
                    + np.float64(normal[i, 2]) * direction[i, 2])
        tau = 1.0
        for _ in range(panes[i]):
            tau = tau * two_way
        value = min(max(reflectivity[first_face[p] + face[i]] * cos_i * tau, 0.0), 1.0)
        r = range_m[i]
        noisy = r + sigma * draw
        if value / (r * r) >= threshold and range_min <= noisy <= range_max and cos_i >= cos_limit:
            rows[m], measured[m], exact[m], intensity[m] = i, noisy, r, np.float32(value)
            m += 1
    return m


def rules(sensor) -> np.ndarray:
    """The ``rules`` of :func:`returns` for ``sensor`` (float64 (5,))."""
    r10 = float(sensor.range_at_10pct_m)
    return np.array([sensor.range_noise_sigma_m, 0.1 / (r10 * r10), float(cos(math.radians(sensor.max_incidence_deg))),
                     sensor.range_min_m, sensor.range_max_m], dtype=np.float64)
