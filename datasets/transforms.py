"""Optional transforms of training samples that keep the geometry consistent.

A sample is a dict with per-frame modalities by name (``rgb`` (H, W, 3), ``depth``,
``label``, ``instance`` (H, W), ``normal`` (H, W, 3), ``flow`` (H, W, 2), ... : any entry of
``exporters.modalities.MODALITIES``), ``K`` (3, 3), and ``tracks`` (a dict with ``xy``
(..., 2) pixel positions). Pixel convention: the top-left pixel's centre is (0.5, 0.5), so a
crop shifts positions by the crop's origin and a resize scales them by the size ratio,
exactly; ``K`` changes the same way. Each modality is resampled by the rule its entry
declares (``resample``): ids by nearest neighbour (never blended); colour by area averaging
(PIL's box filter) when shrinking, bilinear when enlarging; depth, normals and flow
bilinearly at the new pixel centres where the four source pixels lie on one continuous
surface, by nearest neighbour across depth edges and next to missing values; normals are
renormalised; flow vectors are scaled by the resize ratio of their axis (a crop leaves them
unchanged).

Objects (``FrameDataset(..., annotations=True)``): ``masks`` (n, H, W) are resampled like
ids; in ``boxes2d`` the amodal boxes move with the image and are clipped to it, and the
visible boxes and areas are recomputed exactly from the transformed ``instance`` map (or the
masks), so they stay the tight boxes of the masks; objects left without a pixel are dropped
from ``boxes2d`` (and ``masks``). ``boxes3d`` are in the world frame and do not change.
"""

from __future__ import annotations

import numpy as np
from PIL import Image

from exporters.modalities import MODALITIES
from generator.checks import check_integer
from generator.geometry.boxes import tight_boxes

EDGE_RATIO = 1.05  # four source depths spanning more than 5% make a depth edge: nearest there


def _image_keys(sample: dict) -> list[str]:
    return [k for k in sample if k in MODALITIES and isinstance(sample[k], np.ndarray) and sample[k].ndim >= 2]


def _tracks(sample: dict, fn, width: int, height: int) -> None:
    """Move track positions ``xy`` with the image; a point that leaves the new ``width`` x
    ``height`` image is no longer ``visible`` (docs/conventions.md, rule 1)."""
    for key in ("tracks", "tracks_next"):
        if key in sample and sample[key] is not None and "xy" in sample[key]:
            xy = fn(np.asarray(sample[key]["xy"], np.float64))
            new = dict(sample[key]) | {"xy": xy}
            if "visible" in new:
                inside = (xy[..., 0] >= 0) & (xy[..., 0] < width) & (xy[..., 1] >= 0) & (xy[..., 1] < height)
                new["visible"] = np.asarray(new["visible"], bool) & inside
            sample[key] = new


def _objects(out: dict, move, width: int, height: int, resample) -> None:
    """Make ``masks`` and ``boxes2d`` follow an image transform: ``move`` maps pixel positions
    (n, 2) to the new image of ``width`` x ``height``, ``resample`` maps an (H, W) id image."""
    if "masks" in out:
        out["masks"] = np.stack([resample(m) for m in out["masks"]]) if len(out["masks"]) else \
            np.zeros((0, height, width), bool)
    if out.get("boxes2d") is None:
        return
    b = dict(out["boxes2d"])
    n = len(b["instance_id"])
    if "masks" in out:
        boxes, area = np.zeros((n, 4)), out["masks"].reshape(n, -1).sum(1)
        for k, m in enumerate(out["masks"]):
            boxes[k] = tight_boxes(m.astype(np.int8), np.array([1]))[0][0]
    elif "instance" in out:
        boxes, area = tight_boxes(out["instance"], b["instance_id"])
    else:
        raise ValueError("boxes2d can only be transformed exactly with the sample's instance map (or masks): "
                         "keep 'instance' in the dataset's keys")
    amodal = move(np.asarray(b["amodal_bbox"], np.float64).reshape(-1, 2)).reshape(-1, 4)
    b["amodal_bbox"] = np.clip(amodal, 0, [width, height, width, height])
    b["bbox"], b["area"] = boxes, area.astype(np.int64)
    keep = area > 0
    out["boxes2d"] = {k: (v[keep] if isinstance(v, np.ndarray) and len(v) == n else v) for k, v in b.items()}
    if "masks" in out:
        out["masks"] = out["masks"][keep]


class Crop:
    """Keep the window x in [x0, x0 + width), y in [y0, y0 + height) (pixels)."""

    def __init__(self, x0: int, y0: int, width: int, height: int):
        self.x0, self.y0 = check_integer("Crop x0", x0, 0), check_integer("Crop y0", y0, 0)
        self.width, self.height = check_integer("Crop width", width, 1), check_integer("Crop height", height, 1)

    def __call__(self, sample: dict) -> dict:
        out = dict(sample)
        for key in _image_keys(out):
            img = out[key]
            if self.y0 + self.height > img.shape[0] or self.x0 + self.width > img.shape[1]:
                raise ValueError(f"crop window {(self.x0, self.y0, self.width, self.height)} exceeds the "
                                 f"{img.shape[1]}x{img.shape[0]} image")
            out[key] = img[self.y0:self.y0 + self.height, self.x0:self.x0 + self.width]
        _objects(out, lambda xy: xy - [self.x0, self.y0], self.width, self.height,
                 lambda m: m[self.y0:self.y0 + self.height, self.x0:self.x0 + self.width])
        if "K" in out:
            K = np.array(out["K"], np.float64)
            K[0, 2] -= self.x0
            K[1, 2] -= self.y0
            out["K"] = K
        _tracks(out, lambda xy: xy - [self.x0, self.y0], self.width, self.height)
        return out


class _Taps:
    """Bilinear taps of new pixel centres at source positions ``x``, ``y`` (H', W') (pixels,
    the source's top-left pixel centre at (0.5, 0.5)): rows r0, r1 = r0 + 1 (clamped) with
    weights, columns likewise, the nearest source pixel, and whether the position lies in the
    source image."""

    def __init__(self, x: np.ndarray, y: np.ndarray, w: int, h: int):
        def axis(p, n_src):
            c = p - 0.5  # in source pixel-centre units
            with np.errstate(invalid="ignore"):
                lo = np.clip(np.floor(np.nan_to_num(c)).astype(np.int64), 0, n_src - 1)
                t = np.clip(c - np.floor(c), 0, 1)
                t = np.where(c < 0, 0.0, np.where(c > n_src - 1, 1.0, t))
                near = np.minimum(np.clip(np.nan_to_num(p), 0, None).astype(np.int64), n_src - 1)
            return lo, np.clip(lo + 1, 0, n_src - 1), t, near

        self.x, self.y = x, y
        self.c0, self.c1, self.tx, self.cn = axis(x, w)
        self.r0, self.r1, self.ty, self.rn = axis(y, h)
        with np.errstate(invalid="ignore"):
            self.inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)

    @classmethod
    def scaled(cls, w: int, h: int, width: int, height: int) -> "_Taps":
        """The taps of a ``width`` x ``height`` image resized from ``w`` x ``h``."""
        x = np.broadcast_to(((np.arange(width) + 0.5) * w / width)[None, :], (height, width))
        y = np.broadcast_to(((np.arange(height) + 0.5) * h / height)[:, None], (height, width))
        return cls(x, y, w, h)

    def nearest(self, img: np.ndarray) -> np.ndarray:
        return img[self.rn, self.cn]

    def corners(self, img: np.ndarray):
        return img[self.r0, self.c0], img[self.r0, self.c1], img[self.r1, self.c0], img[self.r1, self.c1]

    def bilinear(self, img: np.ndarray, smooth: np.ndarray) -> np.ndarray:
        """Bilinear where ``smooth`` (H', W') and all four taps are finite, else nearest."""
        a, b, c, d = (v.astype(np.float64) for v in self.corners(img))
        tx, ty = self.tx, self.ty
        if img.ndim == 3:
            tx, ty = tx[..., None], ty[..., None]
        with np.errstate(invalid="ignore"):  # inf taps: replaced by the nearest value below
            value = (a * (1 - tx) + b * tx) * (1 - ty) + (c * (1 - tx) + d * tx) * ty
        finite = np.isfinite(np.stack([a, b, c, d]))
        ok = smooth & (finite.all(axis=(0, -1)) if img.ndim == 3 else finite.all(axis=0))
        near = self.nearest(img).astype(np.float64)
        return np.where(ok[..., None] if img.ndim == 3 else ok, value, near)

    def continuous(self, depth: np.ndarray | None, instance: np.ndarray | None = None) -> np.ndarray:
        """(H', W') bool: the four source depths are finite and within EDGE_RATIO of each other;
        without depth, the four taps hold one object (``instance`` >= 0); without either,
        nowhere (nothing tells a surface from the next, so no value is blended)."""
        if depth is None:
            if instance is None:
                return np.zeros(self.r0.shape, bool)
            a, b, c, d = self.corners(instance)
            return (a >= 0) & (a == b) & (a == c) & (a == d)
        taps = np.stack([v.astype(np.float64) for v in self.corners(depth)])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.isfinite(taps).all(0) & (taps.min(0) > 0) & (taps.max(0) <= EDGE_RATIO * taps.min(0))


class Resize:
    """Resize to ``width`` x ``height`` pixels."""

    def __init__(self, width: int, height: int):
        self.width, self.height = check_integer("Resize width", width, 1), check_integer("Resize height", height, 1)

    def __call__(self, sample: dict) -> dict:
        out = dict(sample)
        keys = _image_keys(out)
        if not keys:
            if any(k in out for k in ("K", "tracks", "boxes2d", "masks")):
                raise ValueError("Resize needs an image in the sample to know the size it scales from (K and "
                                 "track positions follow it): load at least one image key, e.g. keys=('label',)")
            return out
        h, w = out[keys[0]].shape[:2]
        sx, sy = self.width / w, self.height / h
        taps = _Taps.scaled(w, h, self.width, self.height)
        smooth = taps.continuous(out.get("depth"), out.get("instance"))
        for key in keys:
            rule, img = MODALITIES[key].resample, out[key]
            if rule == "nearest":
                out[key] = taps.nearest(img)
            elif rule == "area":
                rgb = np.asarray(img, np.float32)
                method = Image.BOX if sx <= 1 and sy <= 1 else Image.BILINEAR
                chans = [rgb] if rgb.ndim == 2 else [rgb[..., c] for c in range(rgb.shape[2])]
                res = [np.asarray(Image.fromarray(np.ascontiguousarray(c), mode="F").resize((self.width, self.height), method))
                       for c in chans]
                out[key] = (res[0] if rgb.ndim == 2 else np.stack(res, axis=-1)).astype(img.dtype)
            else:
                v = taps.bilinear(img, smooth)
                if rule == "unit_vector":
                    norm = np.linalg.norm(v, axis=-1, keepdims=True)
                    v = np.where(norm > 0, v / np.where(norm > 0, norm, 1), 0.0)
                elif rule == "flow":
                    v = v * [sx, sy]
                out[key] = v.astype(img.dtype)
        _objects(out, lambda xy: xy * [sx, sy], self.width, self.height, taps.nearest)
        if "K" in out:
            out["K"] = np.diag([sx, sy, 1.0]) @ np.asarray(out["K"], np.float64)
        _tracks(out, lambda xy: xy * [sx, sy], self.width, self.height)
        return out


class Undistort:
    """Resample a sample seen through ``lens`` (``Sequence.lens``) into the ideal pinhole image
    of ``K`` (default: the sample's own K) and ``size`` (width, height; default: the
    sample's): each new pixel centre's ray is the pinhole's through K, and its value is read
    where the lens put that ray in the source image (the same surface: planar depth, labels,
    ids and normals are those of the ray, exactly at the source's pixel centres, bilinear
    between them on one surface, nearest across edges; colour bilinear). Flow endpoints are
    undistorted too (new flow = the pinhole position of the old endpoint minus the new pixel
    centre), and so are track positions. Pixels whose ray leaves the source image get no
    value: ids -1, depth +inf, colour and normals 0, other values NaN."""

    def __init__(self, lens, K=None, size=None):
        self.lens = lens
        self.K = None if K is None else np.asarray(K, np.float64)
        self.size = None if size is None else (check_integer("Undistort width", size[0], 1),
                                               check_integer("Undistort height", size[1], 1))

    def _to_pixels(self, K_src: np.ndarray, K_dst: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """Pinhole positions (..., 2) in K_dst of source positions ``xy`` (..., 2) seen through
        the lens in K_src (NaN where the lens's inverse does not converge)."""
        b = (xy[..., 1] - K_src[1, 2]) / K_src[1, 1]
        a = (xy[..., 0] - K_src[0, 2] - K_src[0, 1] * b) / K_src[0, 0]
        a, b, ok = self.lens.undistort_where(a, b)
        pixels = np.stack([K_dst[0, 0] * a + K_dst[0, 1] * b + K_dst[0, 2], K_dst[1, 1] * b + K_dst[1, 2]], -1)
        return np.where(ok[..., None], pixels, np.nan)

    def __call__(self, sample: dict) -> dict:
        out = dict(sample)
        keys = _image_keys(out)
        if not keys or "K" not in out:
            raise ValueError("Undistort needs an image and K in the sample (the lens maps through K)")
        h, w = out[keys[0]].shape[:2]
        K_src = np.asarray(out["K"], np.float64)
        K_dst = K_src if self.K is None else self.K
        width, height = self.size or (w, h)
        j, i = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        b = (i - K_dst[1, 2]) / K_dst[1, 1]
        ad, bd = self.lens.distort((j - K_dst[0, 2] - K_dst[0, 1] * b) / K_dst[0, 0], b)
        taps = _Taps(K_src[0, 0] * ad + K_src[0, 1] * bd + K_src[0, 2], K_src[1, 1] * bd + K_src[1, 2], w, h)
        smooth = taps.continuous(out.get("depth"), out.get("instance"))
        for key in keys:
            rule, img = MODALITIES[key].resample, out[key]
            if rule == "nearest":
                v, fill = taps.nearest(img), -1
            else:
                v = taps.bilinear(img, np.ones_like(smooth) if rule == "area" else smooth)
                fill = 0.0 if rule in ("area", "unit_vector") else np.inf if key == "depth" else np.nan
                if rule == "unit_vector":
                    norm = np.linalg.norm(v, axis=-1, keepdims=True)
                    v = np.where(norm > 0, v / np.where(norm > 0, norm, 1), 0.0)
                elif rule == "flow":
                    end = self._to_pixels(K_src, K_dst, np.stack([taps.x, taps.y], -1) + v)
                    v = end - np.stack([j, i], -1)
            v = np.where(taps.inside[..., None] if v.ndim == 3 else taps.inside, v, fill)
            out[key] = v.astype(img.dtype)
        def move(xy):
            return self._to_pixels(K_src, K_dst, xy)

        _objects(out, move, width, height, lambda m: np.where(taps.inside, taps.nearest(m), 0).astype(m.dtype))
        out["K"] = K_dst.copy()
        _tracks(out, move, width, height)
        return out


def srgb_to_linear(rgb: np.ndarray) -> np.ndarray:
    """Display sRGB in [0, 1] -> linear (the IEC 61966-2-1 curve)."""
    c = np.asarray(rgb, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(rgb: np.ndarray) -> np.ndarray:
    c = np.clip(np.asarray(rgb, np.float32), 0, None)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055).astype(np.float32)


class ToLinear:
    """``rgb`` from display sRGB to linear light by the sRGB curve (``rgb_linear`` holds the
    renderer's own scene-linear colour)."""

    def __call__(self, sample: dict) -> dict:
        return dict(sample) | ({"rgb": srgb_to_linear(sample["rgb"])} if "rgb" in sample else {})


class Compose:
    """Transforms applied in order: ``Compose(Crop(...), ToLinear())`` or, as torchvision
    takes them, ``Compose([Crop(...), ToLinear()])``."""

    def __init__(self, *transforms):
        if len(transforms) == 1 and isinstance(transforms[0], (list, tuple)):
            transforms = tuple(transforms[0])
        for t in transforms:
            if not callable(t):
                raise TypeError(f"Compose takes callables (transforms), got {type(t).__name__}: {t!r}")
        self.transforms = transforms

    def __call__(self, sample: dict) -> dict:
        for t in self.transforms:
            sample = t(sample)
        return sample
