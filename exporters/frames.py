"""Per-frame image files of one trajectory and their reader (one schema, here).

For frame N the frames sink writes ``frame_NNNNNN.exr`` (every modality with an EXR part:
see exr.py) and the PNG files the modality table asks for: ``rgb_NNNNNN.png`` (8-bit
display sRGB), ``label_NNNNNN.png`` and ``instance_NNNNNN.png`` (16-bit, id + 1, 0 = none).
``frames.json`` lists the modalities written, their files, channels and conventions;
:class:`FrameReader` reads frames back by modality name.
"""

from __future__ import annotations

import io
import json
import zlib
from pathlib import Path

import numpy as np
from PIL import Image

from generator.geometry.lens import PINHOLE, Lens
from generator.image_sensor import IDEAL, ImageSensor

from .exr import read_frame_exr, write_frame
from .hdf5 import REMEDY, DamagedFileError, access_error
from .jsonfile import read_checked_bytes
from .modalities import MODALITIES, Modality, produced_by
from .sinks import FrameRecord, TrajectoryContext, register_sink

INDEX_FILE = "frames.json"
ID16_MAX = 65534  # largest id a 16-bit id PNG holds (stored as id + 1)


def frame_names(index: int) -> tuple[str, str]:
    """(EXR name, display PNG name) of frame ``index``."""
    return f"frame_{index:06d}.exr", f"rgb_{index:06d}.png"


def png_name(prefix: str, index: int) -> str:
    return f"{prefix}_{index:06d}.png"


def write_png(path: Path, array: np.ndarray, kind: str, name: str) -> None:
    """``rgb8``: display colour in [0, 1] -> 8-bit sRGB (rounded); ``id16``: ids -> 16-bit id + 1."""
    if kind == "rgb8":
        img = (np.clip(array, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    elif kind == "id16":
        ids = np.asarray(array)
        if ids.size and ids.max() > ID16_MAX:
            raise ValueError(f"{name} id {int(ids.max())} does not fit a 16-bit PNG (at most {ID16_MAX}); "
                             f"leave {name} PNGs out or use the EXR")
        img = (ids.astype(np.int64) + 1).astype(np.uint16)
    else:
        raise ValueError(f"unknown PNG kind {kind!r}")
    Image.fromarray(img).save(path, compress_level=1)


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def checked_png_bytes(path: Path) -> bytes:
    """The bytes of the PNG ``path`` once every chunk's CRC-32 matches its contents and the
    file ends with its IEND chunk (Pillow checks neither for the image data, so a flipped
    bit would decode as other pixels); a mismatch raises ValueError naming the chunk."""
    data = Path(path).read_bytes()
    if not data.startswith(PNG_SIGNATURE):
        raise ValueError(f"{path}: not a PNG file")
    pos, kind = len(PNG_SIGNATURE), b""
    while kind != b"IEND":
        if pos + 12 > len(data):
            raise ValueError(f"{path}: truncated PNG (no IEND chunk)")
        length = int.from_bytes(data[pos:pos + 4], "big")
        end = pos + 8 + length
        kind = data[pos + 4:pos + 8]
        if end + 4 > len(data) or zlib.crc32(data[pos + 4:end]) != int.from_bytes(data[end:end + 4], "big"):
            raise ValueError(f"{path}: damaged PNG (chunk {kind.decode('latin-1')!r} at byte {pos} fails its CRC)")
        pos = end + 4
    if pos != len(data):
        raise ValueError(f"{path}: damaged PNG ({len(data) - pos} bytes after its IEND chunk)")
    return data


def read_png(path: Path, kind: str) -> np.ndarray:
    """Inverse of :func:`write_png`: float32 colour in [0, 1], or int32 ids (-1 = none), read
    once its CRCs check (:func:`checked_png_bytes`). A PNG of another kind (not 8-bit RGB for
    colour, not 16-bit grey for ids) or a damaged one raises ValueError."""
    with Image.open(io.BytesIO(checked_png_bytes(path))) as im:
        mode = im.mode
        data = np.asarray(im)
    if kind == "rgb8":
        if mode not in ("RGB", "RGBA"):
            raise ValueError(f"{path}: a {mode} PNG, not the 8-bit RGB colour image this file should hold")
        return (data[..., :3].astype(np.float32) / np.float32(255.0)).astype(np.float32)
    if data.ndim != 2 or data.dtype != np.uint16:
        raise ValueError(f"{path}: a {mode} PNG, not the 16-bit grey id image this file should hold")
    return data.astype(np.int32) - 1


@register_sink("frames")
class FramesSink:
    """Writes every frame's modalities (``context.modalities``) into the trajectory folder."""

    def __init__(self, context: TrajectoryContext, compression: str = "zip"):
        self.folder = Path(context.folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.names = tuple(context.modalities)
        self.compression = compression
        self.attributes = {"buildee/labels": json.dumps(list(context.labels))}
        self.frames, self.size = 0, (int(context.width), int(context.height))
        self.camera = {"K": np.asarray(context.K, np.float64).tolist(), "lens": context.lens.as_dict(),
                       "meaning": "K in pixels (OpenCV); the lens maps normalised camera coordinates to the "
                                  "distorted ones K applies to, with OpenCV's definitions (docs/cameras.md); "
                                  "every modality is of the pixel centres through it"}
        # planar metres; an infinite limit is written as null (JSON has no infinity)
        self.clip = tuple(float(c) if np.isfinite(c) else None for c in context.clip)
        # the Simulator's settings that decide how depth, labels and ids were made (frames.json;
        # None where the caller's context does not say)
        self.ground_truth = context.options.get("ground_truth")
        self.sensitivity = context.options.get("segmentation_sensitivity")
        self.image_sensor, self.gains = context.image_sensor, {}
        self.shutter_s = float(context.options.get("shutter_s", 0.0))
        self.rolling = context.rolling.shutter if context.rolling is not None else None

    def add_frame(self, frame: FrameRecord) -> None:
        i = frame.index
        stored = {n: frame.outputs[n] for n in self.names if MODALITIES[n].part is not None}
        if stored:
            write_frame(self.folder / frame_names(i)[0], stored, self.compression, self.attributes)
        for n in self.names:
            for prefix, kind in MODALITIES[n].pngs:
                write_png(self.folder / png_name(prefix, i), frame.outputs[n], kind, n)
        self.frames = max(self.frames, i + 1)
        self.gains[i] = float(frame.exposure_gain)

    def close(self) -> None:
        doc = {"format": "frames-1", "frames": self.frames, "width": self.size[0], "height": self.size[1],
               "pixels": "pixel (row i, col j) has its centre at (x, y) = (j + 0.5, i + 0.5)",
               "camera": self.camera,
               "clip": {"near": self.clip[0], "far": self.clip[1],
                        "meaning": "planar depth limits in metres of the camera: no surface outside them is seen "
                                   "(depth, labels, ids, normals, flow, tracks)"},
               "ground_truth": self.ground_truth, "segmentation_sensitivity": self.sensitivity,
               "modalities": {n: describe(MODALITIES[n], self.ground_truth, self.sensitivity) for n in self.names}}
        if self.shutter_s > 0:
            doc["shutter"] = {"seconds": self.shutter_s, "meaning": "rgb and rgb_linear are exposed from t - seconds/2 "
                              "to t + seconds/2 around each frame's time t (the camera and the machines moving: "
                              "motion blur); every other modality is of the frame's time t (docs/cameras.md)"}
        if self.rolling is not None:
            doc["rolling_shutter"] = self.rolling.as_dict() | {
                "meaning": "row r of every image (rgb, rgb_linear, depth, labels, ids, normals, flow) shows the scene "
                           "at its row time: the camera at its pose then (the trajectory interpolated between frames), "
                           "the machines where they stood (within 5 mm); flow, tracks and COLMAP keypoints place a "
                           "point at the row that sees it; poses are those of the frame time (docs/cameras.md)"}
        if not self.image_sensor.ideal:
            doc["image_sensor"] = self.image_sensor.as_dict() | {
                "exposure_gain": [self.gains.get(i, 1.0) for i in range(self.frames)],
                "meaning": "what the camera's sensor did to rgb (the display colour) only: decoded by the sRGB "
                           "curve, times exposure_gain (per frame), shot and read noise in electrons of the full "
                           "well, encoded back, JPEG at jpeg_quality (docs/cameras.md); rgb_linear and every "
                           "ground truth are as rendered and cast"}
        (self.folder / INDEX_FILE).write_text(json.dumps(doc, indent=1))


def describe(m: Modality, ground_truth: str | None = None, segmentation_sensitivity: float | None = None) -> dict:
    """A modality's entry in frames.json, as made with these Simulator settings."""
    files = ([frame_names(0)[0].replace("000000", "NNNNNN") + f" part {m.part}"] if m.part else []) + [
        png_name(p, 0).replace("000000", "NNNNNN") + (" (8-bit sRGB)" if k == "rgb8" else " (16-bit, id + 1, 0 = none)")
        for p, k in m.pngs]
    return {"description": m.description, "source": produced_by(m, ground_truth, segmentation_sensitivity),
            "channels": list(m.channels) if m.part else [],
            "exr_type": m.exr_type if m.part else None, "dtype": m.dtype, "files": files}


def exact_png(name: str) -> bool:
    """Whether modality ``name``'s first PNG holds exactly its EXR values: ids in a 16-bit PNG
    (id + 1; the writer refuses ids that do not fit). Display colour (8-bit) is not exact."""
    pngs = MODALITIES[name].pngs
    return bool(pngs) and pngs[0][1] == "id16" and MODALITIES[name].is_ids


class FrameReader:
    """Reads the frames of one trajectory folder by modality name (``frames.json`` says
    which were written). Damaged or missing files raise DamagedFileError naming them; a file
    this process cannot open (too many open files, no permission) raises AccessError."""

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        path = self.folder / INDEX_FILE
        try:
            doc = json.loads(read_checked_bytes(path))
            self.modalities: tuple[str, ...] = tuple(doc["modalities"])
            self.frames, self.width, self.height = int(doc["frames"]), int(doc["width"]), int(doc["height"])
            camera = doc.get("camera")  # written since #41
            self.K = None if camera is None else np.asarray(camera["K"], np.float64)
            self.lens = PINHOLE if camera is None else Lens.from_dict(camera["lens"])
            self.shutter_s = float(doc.get("shutter", {}).get("seconds", 0.0))  # written with motion blur (#41)
            # seconds from the first row's time to the last's (0: a global shutter; #41)
            self.readout_s = float(doc.get("rolling_shutter", {}).get("readout_s", 0.0))
            sensor = doc.get("image_sensor")  # written when the sensor changes rgb (#41)
            self.image_sensor = IDEAL if sensor is None else ImageSensor.from_dict(sensor)
            self.exposure_gain = np.ones(self.frames) if sensor is None else np.asarray(sensor["exposure_gain"],
                                                                                         np.float64)
            if self.exposure_gain.shape != (self.frames,) or not np.all(np.isfinite(self.exposure_gain)):
                raise ValueError("image_sensor.exposure_gain is not one finite number per frame")
        except FileNotFoundError:
            raise DamagedFileError(f"{path}: missing; {REMEDY}") from None
        except DamagedFileError:
            raise
        except (OSError, ValueError, KeyError, TypeError) as exc:
            damage = DamagedFileError(f"{path}: damaged file ({exc.__class__.__name__}); {REMEDY}")
            raise access_error(exc, path) or damage from None
        unknown = [n for n in self.modalities if n not in MODALITIES]
        if unknown:
            raise DamagedFileError(f"{path}: modalities {unknown} are not registered in this process "
                                   "(register them before reading)")

    def read(self, index: int, keys=None) -> dict[str, np.ndarray]:
        """Modality name -> array of frame ``index`` for ``keys`` (default: all written).

        The frame EXR is decoded whole (OpenEXR's Python API reads every part), so it is left
        unopened when every requested modality has a file of its own with the same values:
        ``rgb`` (its PNG), ``label`` and ``instance`` (their 16-bit PNGs, exact)."""
        keys = self.modalities if keys is None else tuple(keys)
        missing = [k for k in keys if k not in self.modalities]
        if missing:
            raise KeyError(f"{self.folder}: no modality {', '.join(missing)} (written: {', '.join(self.modalities)})")
        out = {}
        in_exr = [k for k in keys if MODALITIES[k].part is not None]
        if in_exr and all(exact_png(k) for k in in_exr):  # ids only: their PNGs hold the same values,
            in_exr = []                                   # ~20x cheaper than decoding every EXR part
        if in_exr:
            path = self.folder / frame_names(index)[0]
            if not path.is_file():
                raise DamagedFileError(f"{path}: missing frame; {REMEDY}")
            exr = read_frame_exr(path, in_exr)
            absent = [k for k in in_exr if k not in exr]
            if absent:
                raise DamagedFileError(f"{self.folder / frame_names(index)[0]}: damaged frame (no "
                                       f"{', '.join(absent)}); {REMEDY}")
            out |= {k: exr[k] for k in in_exr}
        for k in keys:
            if k not in out:
                prefix, kind = MODALITIES[k].pngs[0]
                path = self.folder / png_name(prefix, index)
                if not path.is_file():
                    raise DamagedFileError(f"{path}: missing frame file; {REMEDY}")
                try:
                    out[k] = read_png(path, kind)
                except OSError as exc:
                    damage = DamagedFileError(f"{path}: damaged PNG ({exc.__class__.__name__}); {REMEDY}")
                    raise access_error(exc, path) or damage from None
                except ValueError as exc:
                    raise DamagedFileError(f"{exc}; {REMEDY}") from None
        shape = (self.height, self.width)
        bad = [k for k, v in out.items() if v.shape[:2] != shape]
        if bad:
            raise DamagedFileError(f"{self.folder}: frame {index} ({', '.join(bad)}) is not "
                                   f"{self.width}x{self.height} pixels; {REMEDY}")
        return {k: out[k] for k in keys}
