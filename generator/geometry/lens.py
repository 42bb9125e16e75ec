"""Lens models: where a camera-frame direction lands on the image, and the ray through a pixel
(bpy-free; docs/cameras.md).

A point (x, y, z) of the OpenCV camera frame (x right, y down, z forward; z > 0) has the
normalised coordinates (a, b) = (x / z, y / z). The lens maps them to distorted normalised
coordinates (a_d, b_d), and ``K`` maps those to pixels (generator/geometry/camera.py's
convention: pixel (row i, col j) has its centre at (j + 0.5, i + 0.5)):
u = fx a_d + s b_d + cx, v = fy b_d + cy. The models, with OpenCV's definitions:

- ``pinhole``: (a_d, b_d) = (a, b); no coefficients.
- ``opencv`` (``cv2.projectPoints``; COLMAP's OPENCV, and FULL_OPENCV's first five),
  coefficients (k1, k2, p1, p2, k3): with s = a^2 + b^2 and R = 1 + k1 s + k2 s^2 + k3 s^3,
  a_d = a R + 2 p1 a b + p2 (s + 2 a^2), b_d = b R + p1 (s + 2 b^2) + 2 p2 a b.
- ``fisheye`` (``cv2.fisheye``, the equidistant model; COLMAP's OPENCV_FISHEYE),
  coefficients (k1, k2, k3, k4): with r = sqrt(a^2 + b^2), theta = atan(r) (the angle from
  the optical axis) and theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
  (a_d, b_d) = (theta_d / r) (a, b), and (a, b) itself at r = 0. Only directions in front of
  the camera (z > 0) have an image: the field of view stays under 180 degrees, as OpenCV's.

:meth:`Lens.rays` inverts the map at every pixel centre by Newton's method, to float64
round-off (the residual is checked), so a ray cast through pixel (i, j) lands, projected
back, on (j + 0.5, i + 0.5) to about 1e-9 pixels. The inverse exists where the map is
one-to-one: :meth:`Lens.check` refuses coefficients whose radial map folds back (its
derivative reaches zero) inside the image. Arithmetic is IEEE float64 in a fixed order with
the project's portable arctangent and tangent (generator/geometry/portable_math.py): the same
bits on every CPU.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import portable_math

# model -> its coefficients' names, in OpenCV's order
MODELS = {
    "pinhole": (),
    "opencv": ("k1", "k2", "p1", "p2", "k3"),
    "fisheye": ("k1", "k2", "k3", "k4"),
}
NEWTON_STEPS = 30  # Newton's iterations of the inverse (it converges in under 10 on usable lenses)
INVERSE_TOL = 1e-12  # the largest residual |distort(undistort(p)) - p| accepted (normalised units)
FOLD_SAMPLES = 4096  # radial samples searched for a fold of the map


@dataclass(frozen=True)
class Lens:
    """A lens model (one of :data:`MODELS`) and its coefficients, with OpenCV's definitions
    (the module's docstring). ``Lens()`` is the ideal pinhole."""

    model: str = "pinhole"
    coefficients: tuple[float, ...] = ()

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"lens model {self.model!r} is unknown: use one of {', '.join(MODELS)}")
        names = MODELS[self.model]
        values = tuple(float(c) for c in self.coefficients)
        if self.model == "opencv" and len(values) == 4:
            values = values + (0.0,)  # k3 = 0, as OpenCV's four-coefficient form
        if len(values) != len(names):
            if not names:
                raise ValueError(f"a pinhole lens takes no coefficients, got {len(self.coefficients)}: give a "
                                 "lens model (opencv or fisheye) with them")
            raise ValueError(f"a {self.model} lens takes {len(names)} ({', '.join(names)}) coefficients, "
                             f"got {len(self.coefficients)}")
        if not all(np.isfinite(values)):
            raise ValueError(f"lens coefficients must be finite numbers, got {list(self.coefficients)}")
        object.__setattr__(self, "coefficients", values)

    @property
    def ideal(self) -> bool:
        """True when the lens maps every direction as a pinhole (no distortion; a fisheye
        without coefficients is still the equidistant projection)."""
        return self.model == "pinhole" or (self.model == "opencv" and not any(self.coefficients))

    def as_dict(self) -> dict:
        """The lens as files write it (frames.json, tracks.h5, ground_truth.h5): its model and
        named coefficients, ``{"model": "opencv", "k1": ..., "k2": ..., "p1": ..., "p2": ..., "k3": ...}``."""
        return {"model": self.model} | dict(zip(MODELS[self.model], self.coefficients))

    @classmethod
    def from_dict(cls, d: dict) -> "Lens":
        """The reader of :meth:`as_dict` (ValueError in one line for anything else)."""
        if not isinstance(d, dict) or d.get("model") not in MODELS:
            raise ValueError(f"a lens must be a dict with a model in {', '.join(MODELS)}, got {str(d)[:80]}")
        names = MODELS[d["model"]]
        if set(d) != {"model", *names}:
            raise ValueError(f"a {d['model']} lens has the keys model, {', '.join(names) or '(no coefficients)'}; "
                             f"got {', '.join(sorted(d))}")
        return cls(d["model"], tuple(d[n] for n in names))

    def colmap_camera(self, K: np.ndarray) -> tuple[str, list[float]]:
        """COLMAP's camera model and parameters for this lens and ``K`` (no skew): PINHOLE,
        OPENCV (k3 = 0) or FULL_OPENCV (k4..k6 = 0), OPENCV_FISHEYE."""
        fx, fy, cx, cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
        if self.model == "fisheye":
            return "OPENCV_FISHEYE", [fx, fy, cx, cy, *self.coefficients]
        if self.model == "opencv" and any(self.coefficients):
            k1, k2, p1, p2, k3 = self.coefficients
            if k3 == 0.0:
                return "OPENCV", [fx, fy, cx, cy, k1, k2, p1, p2]
            return "FULL_OPENCV", [fx, fy, cx, cy, k1, k2, p1, p2, k3, 0.0, 0.0, 0.0]
        return "PINHOLE", [fx, fy, cx, cy]

    @classmethod
    def from_colmap(cls, model: str, params) -> tuple[tuple[float, float, float, float], "Lens"]:
        """((fx, fy, cx, cy), lens) of a COLMAP camera; ValueError for a model no lens here
        matches (FULL_OPENCV with k4..k6 != 0, the other models)."""
        p = [float(v) for v in params]
        counts = {"SIMPLE_PINHOLE": 3, "PINHOLE": 4, "OPENCV": 8, "FULL_OPENCV": 12, "OPENCV_FISHEYE": 8}
        if counts.get(model) != len(p):
            raise ValueError(f"camera model {model} with {len(p)} parameters; PINHOLE, SIMPLE_PINHOLE, OPENCV, "
                             "FULL_OPENCV (k4-k6 zero) or OPENCV_FISHEYE is needed")
        if model == "SIMPLE_PINHOLE":
            return (p[0], p[0], p[1], p[2]), PINHOLE
        if model == "FULL_OPENCV" and any(p[9:]):
            raise ValueError("camera model FULL_OPENCV with k4-k6 (the rational model); only k1, k2, p1, p2, k3 are "
                             "supported: undistort first")
        if model == "PINHOLE":
            return tuple(p), PINHOLE
        named, end = {"OPENCV": ("opencv", 8), "FULL_OPENCV": ("opencv", 9), "OPENCV_FISHEYE": ("fisheye", 8)}[model]
        return tuple(p[:4]), cls(named, tuple(p[4:end]))

    def nerfstudio_fields(self) -> dict:
        """transforms.json's camera model and distortion fields (nerfstudio's names)."""
        if self.model == "fisheye":
            return {"camera_model": "OPENCV_FISHEYE"} | dict(zip(("k1", "k2", "k3", "k4"), self.coefficients))
        k1, k2, p1, p2, k3 = self.coefficients if self.model == "opencv" else (0.0,) * 5
        return {"camera_model": "OPENCV", "k1": k1, "k2": k2, "k3": k3, "k4": 0.0, "p1": p1, "p2": p2}

    # ---- the forward map --------------------------------------------------------------
    def distort(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distorted normalised coordinates (a_d, b_d) of normalised (a, b) (float64 arrays)."""
        a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
        if self.model == "opencv":
            k1, k2, p1, p2, k3 = self.coefficients
            s = a * a + b * b
            radial = 1.0 + s * (k1 + s * (k2 + s * k3))
            ab = a * b
            return (a * radial + 2.0 * p1 * ab + p2 * (s + 2.0 * a * a),
                    b * radial + p1 * (s + 2.0 * b * b) + 2.0 * p2 * ab)
        if self.model == "fisheye":
            r = np.sqrt(a * a + b * b)
            theta = portable_math.atan2(r, np.ones_like(r))
            scale = np.divide(self._theta_d(theta), r, out=np.ones_like(r), where=r > 0)
            return a * scale, b * scale
        return a.copy(), b.copy()

    def project(self, K: np.ndarray, points_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (N, 2) of camera-frame points (N, 3) through this lens and ``K``, and their
        planar depth z (N,); points with z <= 0 project to NaN."""
        p = np.asarray(points_cam, dtype=np.float64)
        z = p[:, 2]
        front = z > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            a = np.where(front, p[:, 0] / z, np.nan)
            b = np.where(front, p[:, 1] / z, np.nan)
        ad, bd = self.distort(a, b)
        return np.stack([K[0, 0] * ad + K[0, 1] * bd + K[0, 2], K[1, 1] * bd + K[1, 2]], axis=1), z

    # ---- the inverse: rays through pixels -------------------------------------------------
    def rays(self, K: np.ndarray, width: int, height: int) -> np.ndarray:
        """Camera-frame directions (H, W, 3) through the pixel centres, scaled so that z = 1
        (a cast's parameter along them is planar depth)."""
        from .camera import pixel_rays

        if self.ideal:
            return pixel_rays(K, width, height)
        j, i = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        bd = (i - K[1, 2]) / K[1, 1]
        ad = (j - K[0, 2] - K[0, 1] * bd) / K[0, 0]
        a, b = self.undistort(ad, bd)
        return np.stack([a, b, np.ones_like(a)], axis=-1)

    def undistort(self, ad: np.ndarray, bd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normalised (a, b) whose distorted coordinates are (ad, bd): the inverse map, to
        float64 round-off (ValueError where it does not converge: a lens that folds there)."""
        a, b, converged = self.undistort_where(ad, bd)
        if not np.all(converged):
            raise ValueError(f"the {self.model} lens {list(self.coefficients)} cannot be inverted at every pixel (it "
                             "folds back inside the image); use smaller distortion coefficients")
        return a, b

    def undistort_where(self, ad: np.ndarray, bd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As :meth:`undistort`, never raising: (a, b, converged), ``converged`` (bool) False
        where the inverse did not reach float64 round-off (a, b there are meaningless)."""
        ad, bd = np.asarray(ad, dtype=np.float64), np.asarray(bd, dtype=np.float64)
        if self.ideal:
            return ad.copy(), bd.copy(), np.ones(ad.shape, bool)
        with np.errstate(all="ignore"):
            a, b = (self._undistort_fisheye if self.model == "fisheye" else self._undistort_opencv)(ad, bd)
            ra, rb = self.distort(a, b)
            residual = np.maximum(np.abs(ra - ad), np.abs(rb - bd))
            converged = residual <= INVERSE_TOL * np.maximum(1.0, np.abs(ad) + np.abs(bd))
        return a, b, converged

    def _undistort_opencv(self, ad, bd):
        k1, k2, p1, p2, k3 = self.coefficients
        a, b = ad.copy(), bd.copy()
        for _ in range(NEWTON_STEPS):
            s = a * a + b * b
            radial = 1.0 + s * (k1 + s * (k2 + s * k3))
            slope = k1 + s * (2.0 * k2 + s * 3.0 * k3)  # dR / ds
            fa = a * radial + 2.0 * p1 * a * b + p2 * (s + 2.0 * a * a) - ad
            fb = b * radial + p1 * (s + 2.0 * b * b) + 2.0 * p2 * a * b - bd
            cross = 2.0 * a * b * slope + 2.0 * p1 * a + 2.0 * p2 * b  # d a_d / d b = d b_d / d a
            jaa = radial + 2.0 * a * a * slope + 2.0 * p1 * b + 6.0 * p2 * a
            jbb = radial + 2.0 * b * b * slope + 6.0 * p1 * b + 2.0 * p2 * a
            det = jaa * jbb - cross * cross
            a = a - (jbb * fa - cross * fb) / det
            b = b - (jaa * fb - cross * fa) / det
        return a, b

    def _undistort_fisheye(self, ad, bd):
        rd = np.sqrt(ad * ad + bd * bd)  # theta_d
        theta = rd.copy()
        for _ in range(NEWTON_STEPS):
            theta = theta - (self._theta_d(theta) - rd) / self._theta_d_slope(theta)
        s, c = portable_math.sincos(theta)
        r = s / c  # tan(theta)
        scale = np.divide(r, rd, out=np.ones_like(rd), where=rd > 0)
        return ad * scale, bd * scale

    def _theta_d(self, theta):
        k1, k2, k3, k4 = self.coefficients
        t2 = theta * theta
        return theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))

    def _theta_d_slope(self, theta):
        k1, k2, k3, k4 = self.coefficients
        t2 = theta * theta
        return 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))

    def covering_pinhole(self, K: np.ndarray, width: int, height: int) -> tuple[np.ndarray, int, int]:
        """A pinhole (K', width', height') whose image holds every direction this lens images
        in its ``width`` x ``height`` image (the box of the undistorted image border, sampled
        at a quarter pixel, grown by 0.1%): a test "inside the image" through it is
        conservative, and exact once followed by :meth:`project`."""
        u = np.linspace(0.0, width, 4 * width + 1)
        v = np.linspace(0.0, height, 4 * height + 1)
        border_u = np.concatenate([u, u, np.zeros_like(v), np.full_like(v, width)])
        border_v = np.concatenate([np.zeros_like(u), np.full_like(u, height), v, v])
        bd = (border_v - K[1, 2]) / K[1, 1]
        a, b = self.undistort((border_u - K[0, 2] - K[0, 1] * bd) / K[0, 0], bd)
        (a0, a1), (b0, b1) = (a.min(), a.max()), (b.min(), b.max())
        grow_a, grow_b = 1e-3 * (a1 - a0), 1e-3 * (b1 - b0)
        a0, a1, b0, b1 = a0 - grow_a, a1 + grow_a, b0 - grow_b, b1 + grow_b
        fx, fy = float(K[0, 0]), float(K[1, 1])
        cover = np.array([[fx, 0.0, -fx * a0], [0.0, fy, -fy * b0], [0.0, 0.0, 1.0]])
        return cover, int(np.ceil(fx * (a1 - a0))) + 1, int(np.ceil(fy * (b1 - b0))) + 1

    # ---- validity --------------------------------------------------------------------------
    def check(self, K: np.ndarray, width: int, height: int) -> None:
        """ValueError (one line) unless the map is one-to-one over the image: the radial map
        must keep growing out to the image's farthest corner (for a fisheye, also before 90
        degrees)."""
        if self.ideal:
            return
        corners_d = self._corner_radius(K, width, height)
        reach = self._monotonic_reach()
        if corners_d >= reach:
            raise ValueError(
                f"the {self.model} lens {list(self.coefficients)} folds back inside the {width}x{height} image "
                f"(its radial map stops growing at distorted radius {reach:.4g}, the image's corners reach "
                f"{corners_d:.4g}); use smaller distortion coefficients or a longer focal length")

    def _corner_radius(self, K, width, height) -> float:
        """The largest distorted normalised radius of the image's corners."""
        bd = (np.array([0.0, 0.0, height, height]) - K[1, 2]) / K[1, 1]
        ad = (np.array([0.0, width, 0.0, width]) - K[0, 2] - K[0, 1] * bd) / K[0, 0]
        return float(np.max(np.sqrt(ad * ad + bd * bd)))

    def _monotonic_reach(self) -> float:
        """The distorted radius up to which the radial map (tangential terms aside) grows."""
        if self.model == "fisheye":
            theta = np.linspace(0.0, np.pi / 2, FOLD_SAMPLES)
            grows = self._theta_d_slope(theta) > 0
            values = self._theta_d(theta)
        else:
            k1, k2, p1, p2, k3 = self.coefficients
            r = np.linspace(0.0, 10.0, FOLD_SAMPLES)  # 10: 84 degrees off axis
            s = r * r
            grows = 1.0 + s * (3.0 * k1 + s * (5.0 * k2 + s * 7.0 * k3)) > 0
            values = r * (1.0 + s * (k1 + s * (k2 + s * k3)))
        stop = int(np.argmin(grows)) if not np.all(grows) else len(grows)
        return float(np.max(values[:stop])) if stop else 0.0


PINHOLE = Lens()


def lens_of(model: str, coefficients=()) -> Lens:
    """The lens ``model`` with ``coefficients`` (none given: all zero), as ``--camera-model`` and
    ``--distortion`` make it (ValueError in one line)."""
    return Lens(model, tuple(coefficients) or (0.0,) * len(MODELS.get(model, ())))
