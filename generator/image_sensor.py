"""What a camera's sensor does to the display image: exposure, shot and read noise, JPEG
(bpy-free; docs/cameras.md, "Exposure and noise").

Blender renders the display-referred colour (its view transform applied) as 16-bit codes
k / 65535 (exporters/modalities.py ``display_rgb``). An :class:`ImageSensor` turns that clean
image into what a real camera would give, in this order, per pixel and channel:

1. **linear signal**: x = the sRGB decoding of the code (IEC 61966-2-1: v / 12.92 below
   0.04045, else ((v + 0.055) / 1.055)^2.4), the light a display would emit for it, which
   stands for the sensor's linear response (a camera's tone curve undone);
2. **exposure**: x g, with g = 2^``exposure_ev`` (fixed), or with ``exposure_ev`` None
   (auto-exposure, average metering) g = 0.18 / (the frame's mean linear luminance,
   0.2126 R + 0.7152 G + 0.0722 B), kept within 2^-3 .. 2^3; the signal saturates at 1
   (full well);
3. **noise** (when ``full_well_e`` is set): with s = min(x g, 1) ``full_well_e`` electrons,
   the sensor reads e = s + sqrt(s) z1 + ``read_noise_e`` z2 (shot noise as its Gaussian
   approximation: the Poisson variance s, exact in mean and variance; read noise Gaussian;
   z1, z2 standard normals from the view's own random stream), and the signal becomes
   clip(e / ``full_well_e``, 0, 1);
4. **encoding**: back through the sRGB curve to the nearest 16-bit code (exactly the inverse
   of step 1 on the code grid); with ``jpeg_quality`` the image is then JPEG-compressed at
   that quality (Pillow's libjpeg, 4:2:0 chroma, integer DCT) and decoded, in 8 bits.

Only the display colour (``rgb``) changes: the scene-linear ``rgb_linear`` stays the
renderer's noiseless one, and depth, labels, ids, normals, flow and every other ground truth
are untouched. Every step uses IEEE arithmetic only (+, -, x, /, sqrt, and a
65,536-entry table of the sRGB curve made by Newton's method), so the bytes are the same on
every CPU; the noise of a view is the stream (seed, "image_sensor", frame, its pose).
"""

from __future__ import annotations

import hashlib
import io
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

CODES = 65535  # the display image's codes: k / CODES
AUTO_TARGET = 0.18  # auto-exposure brings the mean linear luminance here (mid-grey)
AUTO_RANGE_EV = 3  # ... within this many stops either way
LUMA = (0.2126, 0.7152, 0.0722)  # Rec. 709 luminance weights of linear R, G, B


@dataclass(frozen=True)
class ImageSensor:
    """``exposure_ev``: a fixed exposure compensation in stops (0: as rendered), or None for
    auto-exposure; ``full_well_e``: electrons at saturation (None: no noise);
    ``read_noise_e``: read noise sigma in electrons; ``jpeg_quality``: 1-100, or None."""

    exposure_ev: float | None = 0.0
    full_well_e: float | None = None
    read_noise_e: float = 0.0
    jpeg_quality: int | None = None

    def __post_init__(self):
        if self.exposure_ev is not None and not (isinstance(self.exposure_ev, (int, float))
                                                 and math.isfinite(self.exposure_ev) and abs(self.exposure_ev) <= 10):
            raise ValueError(f"exposure must be 'auto' or a number of stops from -10 to 10, got {self.exposure_ev!r}")
        if self.full_well_e is not None and not (isinstance(self.full_well_e, (int, float))
                                                 and 1 <= self.full_well_e <= 1e7):
            raise ValueError(f"full well must be 1 to 10,000,000 electrons, got {self.full_well_e!r}")
        if not (isinstance(self.read_noise_e, (int, float)) and 0 <= self.read_noise_e <= 1e4):
            raise ValueError(f"read noise must be 0 to 10,000 electrons, got {self.read_noise_e!r}")
        if self.read_noise_e > 0 and self.full_well_e is None:
            raise ValueError("read noise needs a full well (electrons at saturation) to be measured against")
        if self.jpeg_quality is not None and not (isinstance(self.jpeg_quality, int) and 1 <= self.jpeg_quality <= 100):
            raise ValueError(f"JPEG quality must be an integer from 1 to 100, got {self.jpeg_quality!r}")

    @property
    def ideal(self) -> bool:
        """The display image passes unchanged."""
        return self.exposure_ev == 0 and self.full_well_e is None and self.jpeg_quality is None

    def as_dict(self) -> dict:
        return {"exposure_ev": "auto" if self.exposure_ev is None else float(self.exposure_ev),
                "full_well_e": self.full_well_e, "read_noise_e": float(self.read_noise_e),
                "jpeg_quality": self.jpeg_quality}

    @classmethod
    def from_dict(cls, d: dict) -> "ImageSensor":
        ev = d.get("exposure_ev", 0.0)
        return cls(None if ev == "auto" else float(ev), d.get("full_well_e"), float(d.get("read_noise_e", 0.0)),
                   d.get("jpeg_quality"))

    def gain(self, linear: np.ndarray) -> float:
        """g of step 2 for the linear image ``linear`` (H, W, 3)."""
        if self.exposure_ev is not None:
            return exposure_gain(float(self.exposure_ev))
        y = LUMA[0] * linear[..., 0] + LUMA[1] * linear[..., 1] + LUMA[2] * linear[..., 2]
        mean = math.fsum(y.ravel().tolist()) / max(1, y.size)  # fsum: exact, in any order
        lo, hi = exposure_gain(-AUTO_RANGE_EV), exposure_gain(AUTO_RANGE_EV)
        return hi if mean <= 0 else min(hi, max(lo, AUTO_TARGET / mean))

    def apply(self, display: np.ndarray, rng: np.random.Generator | None) -> tuple[np.ndarray, float]:
        """(the sensor's display image (H, W, 3) float32 in [0, 1], the gain g) from the clean
        display image ``display`` (codes k / 65535); ``rng``: the view's stream (needed with
        noise)."""
        table = srgb_decoding()
        codes = np.rint(np.clip(np.asarray(display, np.float64), 0.0, 1.0) * CODES).astype(np.int64)
        linear = table[codes]
        g = self.gain(linear)
        signal = np.minimum(linear * g, 1.0)
        if self.full_well_e is not None:
            if rng is None:
                raise ValueError("a noisy sensor needs the view's random stream")
            fw = float(self.full_well_e)
            electrons = signal * fw
            z = rng.standard_normal((2,) + signal.shape)
            electrons = electrons + np.sqrt(electrons) * z[0] + float(self.read_noise_e) * z[1]
            signal = np.clip(electrons / fw, 0.0, 1.0)
        out = (encode_codes(signal, table).astype(np.float64) / CODES).astype(np.float32)
        if self.jpeg_quality is not None:
            out = jpeg_round_trip(out, self.jpeg_quality)
        return out, g


IDEAL = ImageSensor()


def image_sensor_of(exposure="as-rendered", noise=(), jpeg_quality=None) -> ImageSensor:
    """The sensor of the batch job's options: ``exposure`` "as-rendered", "auto" or a number
    of stops (or its text); ``noise`` () or (full well, read noise) in electrons;
    ``jpeg_quality`` None or 1-100. ValueError in one line otherwise."""
    if exposure in ("as-rendered", "auto"):
        ev = 0.0 if exposure == "as-rendered" else None
    else:
        try:
            ev = float(exposure)
        except (TypeError, ValueError):
            raise ValueError(f"exposure must be 'auto', 'as-rendered' or a number of stops, got {exposure!r}") from None
    noise = tuple(noise)
    if len(noise) not in (0, 2):
        raise ValueError(f"sensor noise is two numbers, full well and read noise in electrons (e.g. 6000,3), "
                         f"got {len(noise)}")
    return ImageSensor(ev, float(noise[0]) if noise else None, float(noise[1]) if noise else 0.0, jpeg_quality)


def exposure_gain(ev: float) -> float:
    """2^ev in IEEE arithmetic: 2^whole exactly, times 2^(1/2^i) (i square roots of 2) for
    each of the first 24 binary digits of the fraction (to 2^-24 of a stop)."""
    whole = math.floor(ev)
    frac, gain, r = ev - whole, math.ldexp(1.0, int(whole)), 2.0
    for _ in range(24):
        r = math.sqrt(r)  # 2^(1/2), 2^(1/4), ...
        frac *= 2.0
        if frac >= 1.0:
            gain, frac = gain * r, frac - 1.0
    return gain


def root(c: np.ndarray, n: int) -> np.ndarray:
    """c^(1/n) for c >= 0 (float64), by Newton's method from above after scaling c by a power
    of two^n (exact): the same bits on every CPU (no C-library pow)."""
    c = np.asarray(c, np.float64)
    mantissa, exponent = np.frexp(c)  # c = m 2^e, m in [0.5, 1)
    q = np.floor_divide(exponent, n)
    r = exponent - q * n  # 0 <= r < n: c = (m 2^r) 2^(n q)
    a = np.ldexp(mantissa, r)  # in [0.5, 2^n)
    y = np.full(a.shape, 2.0)  # >= a^(1/n): Newton from above decreases monotonically to the root
    for _ in range(64 + 4 * n.bit_length()):
        p = np.ones_like(y)
        for _ in range(n - 1):
            p = p * y
        y = ((n - 1) * y + a / p) / n
    out = np.ldexp(y, q)
    return np.where(c > 0, out, 0.0)


@lru_cache(maxsize=1)
def srgb_decoding() -> np.ndarray:
    """(65536,) float64: the linear value of every display code k / 65535 (step 1)."""
    v = np.arange(CODES + 1, dtype=np.float64) / CODES
    t = (v + 0.055) / 1.055
    # t^2.4 = t^2 (t^2)^(1/5)
    t2 = t * t
    curve = t2 * root(t2, 5)
    table = np.where(v <= 0.04045, v / 12.92, curve)
    table.setflags(write=False)
    return table


def encode_codes(linear: np.ndarray, table: np.ndarray) -> np.ndarray:
    """The display code whose decoded value is nearest each linear value (ties: the lower)."""
    hi = np.clip(np.searchsorted(table, linear, side="left"), 1, CODES)
    lo = hi - 1
    return np.where(linear - table[lo] <= table[hi] - linear, lo, hi)


def jpeg_round_trip(display: np.ndarray, quality: int) -> np.ndarray:
    """The 8-bit image of ``display`` (rounded as the PNG is) JPEG-compressed at ``quality``
    and decoded, as float32 in [0, 1]."""
    from PIL import Image

    rgb8 = (np.clip(display, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(rgb8).save(buffer, format="JPEG", quality=quality, subsampling=2)
    decoded = np.asarray(Image.open(io.BytesIO(buffer.getvalue())).convert("RGB"))
    return (decoded.astype(np.float32) / np.float32(255.0)).astype(np.float32)


def view_stream(seed: int, frame: int, world_from_camera: np.ndarray) -> np.random.Generator:
    """The noise stream of one view: (seed, "image_sensor", frame, the pose's bytes)."""
    from .geometry.seeding import stream

    pose = hashlib.sha256(np.ascontiguousarray(world_from_camera, np.float64).tobytes()).hexdigest()
    return stream(seed, "image_sensor", int(frame), pose)
