"""Per-frame EXR files: RGB, depth, semantic labels and instance ids in one file.

Channels (single part, scanline, documented in docs/format.md):

| channel    | type   | content                                                          |
|------------|--------|------------------------------------------------------------------|
| R, G, B    | HALF   | colour; display-referred sRGB in [0, 1] unless the header says    |
| Z          | FLOAT  | planar depth in metres (camera z), +inf where no surface         |
| label      | UINT   | semantic label id; 4294967295 (= -1 as int32) means unlabelled   |
| instance   | UINT   | object (instance) id; 4294967295 (= -1 as int32) means none      |

Any subset of the channels may be written. Header attributes ``buildee/*`` state units and
conventions. The reader returns exactly the arrays that were written (RGB as float16,
depth as float32, label and instance as int32 with -1).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import OpenEXR

from .hdf5 import REMEDY, DamagedFileError, damaged

COMPRESSIONS = {
    "none": OpenEXR.NO_COMPRESSION,
    "rle": OpenEXR.RLE_COMPRESSION,
    "zips": OpenEXR.ZIPS_COMPRESSION,
    "zip": OpenEXR.ZIP_COMPRESSION,
    "piz": OpenEXR.PIZ_COMPRESSION,
}
RGB_CHANNELS = ("R", "G", "B")
DEPTH_CHANNEL = "Z"
LABEL_CHANNEL = "label"
INSTANCE_CHANNEL = "instance"
ATTRIBUTES = {
    "buildee/format": "frame-exr-1",
    "buildee/depth": "Z: planar depth (camera z) in metres, float32, +inf = no surface",
    "buildee/label": "label: uint32 label id, 4294967295 (-1 as int32) = unlabelled",
    "buildee/instance": "instance: uint32 object id, 4294967295 (-1 as int32) = none",
    "buildee/pixels": "pixel (row i, col j) has its centre at (x, y) = (j + 0.5, i + 0.5)",
}


def _ids_to_uint32(ids: np.ndarray, name: str) -> np.ndarray:
    ids = np.asarray(ids)
    if ids.ndim != 2 or not np.issubdtype(ids.dtype, np.integer):
        raise ValueError(f"{name} must be a 2D integer array, got {ids.dtype} {ids.shape}")
    if ids.size and (ids.min() < -1 or ids.max() > np.iinfo(np.int32).max):
        raise ValueError(f"{name} ids must lie in [-1, 2^31 - 1]")
    return np.ascontiguousarray(ids.astype(np.int64).astype(np.int32).view(np.uint32))


def write_frame_exr(
    path: str | Path,
    rgb: np.ndarray | None = None,
    depth: np.ndarray | None = None,
    label: np.ndarray | None = None,
    instance: np.ndarray | None = None,
    compression: str = "zip",
    rgb_meaning: str = "display-referred sRGB in [0, 1]",
    attributes: dict[str, str] | None = None,
) -> Path:
    """Write one frame's arrays (all (H, W) or (H, W, 3), same H and W) to an EXR file."""
    if compression not in COMPRESSIONS:
        raise ValueError(f"unknown EXR compression {compression!r}; choose one of {', '.join(COMPRESSIONS)}")
    channels: dict[str, np.ndarray] = {}
    if rgb is not None:
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"rgb must have shape (H, W, 3), got {rgb.shape}")
        for k, c in enumerate(RGB_CHANNELS):
            channels[c] = np.ascontiguousarray(rgb[..., k], dtype=np.float16)
    if depth is not None:
        depth = np.asarray(depth)
        if depth.ndim != 2:
            raise ValueError(f"depth must have shape (H, W), got {depth.shape}")
        channels[DEPTH_CHANNEL] = np.ascontiguousarray(depth, dtype=np.float32)
    if label is not None:
        channels[LABEL_CHANNEL] = _ids_to_uint32(label, "label")
    if instance is not None:
        channels[INSTANCE_CHANNEL] = _ids_to_uint32(instance, "instance")
    if not channels:
        raise ValueError("nothing to write: pass at least one of rgb, depth, label, instance")
    shapes = {c.shape[:2] for c in channels.values()}
    if len(shapes) != 1:
        raise ValueError(f"all arrays must share one (H, W), got {sorted(shapes)}")
    header = {"compression": COMPRESSIONS[compression], "type": OpenEXR.scanlineimage}
    header.update(ATTRIBUTES)
    if rgb is not None:
        header["buildee/rgb"] = rgb_meaning
    for key, value in (attributes or {}).items():
        header[key] = value if isinstance(value, str) else json.dumps(value)
    path = Path(path)
    with OpenEXR.File(header, dict(channels)) as f:  # the library replaces the dict's arrays
        f.write(str(path))
    return path


def read_frame_exr(path: str | Path) -> dict[str, np.ndarray]:
    """Read a frame EXR: returns the written arrays under 'rgb', 'depth', 'label', 'instance'
    (only those present) plus 'header' (the file's attributes). A truncated or damaged file
    raises :class:`~exporters.hdf5.DamagedFileError` naming it (its structure is checked
    before OpenEXR decodes it; ZIP-compressed chunks carry zlib's own checksum)."""
    path = Path(path)
    if not path.is_file():
        raise DamagedFileError(f"{path}: no such file; {REMEDY}")
    check_exr_structure(path)
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            ch = {name: c.pixels for name, c in f.channels().items()}
            header = dict(f.header())
    except (OSError, ValueError, RuntimeError, TypeError) as exc:
        raise damaged(path, f"OpenEXR cannot decode its pixels: {exc.__class__.__name__}") from None
    out: dict = {"header": header}
    if all(c in ch for c in RGB_CHANNELS):
        out["rgb"] = np.stack([ch[c] for c in RGB_CHANNELS], axis=-1)
    if DEPTH_CHANNEL in ch:
        out["depth"] = ch[DEPTH_CHANNEL]
    for key, name in (("label", LABEL_CHANNEL), ("instance", INSTANCE_CHANNEL)):
        if name in ch:
            out[key] = np.ascontiguousarray(ch[name], dtype=np.uint32).view(np.int32)
    return out


_MAGIC = b"\x76\x2f\x31\x01"
_LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}  # by compression id
_SINGLE_PART_FLAGS = 0x200 | 0x800 | 0x1000  # tiled, deep, multi-part: not our frame layout
_MAX_HEADER = 1 << 20


def check_exr_structure(path: Path) -> None:
    """Check a single-part scanline EXR (our frames) is whole: the header parses, and the
    chunk table points at chunks that lie inside the file, each for the scanlines it should
    hold. Other EXR layouts are left to OpenEXR. Raises DamagedFileError."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(min(size, _MAX_HEADER))
        if head[:4] != _MAGIC:
            raise damaged(path, "not an OpenEXR file (bad magic number)" if size >= 4 else "empty or truncated file")
        flags = int.from_bytes(head[4:8], "little")
        if flags & _SINGLE_PART_FLAGS:
            return
        window, compression, pos = _parse_header(head, path)
        y0, y1 = window[1], window[3]
        per = _LINES_PER_CHUNK.get(compression)
        if per is None or y1 < y0:
            raise damaged(path, f"header: compression {compression}, data window {window}")
        chunks = -(-(y1 - y0 + 1) // per)
        table = head[pos:pos + 8 * chunks]
        if len(table) < 8 * chunks:
            f.seek(pos)
            table = f.read(8 * chunks)
        if len(table) < 8 * chunks:
            raise damaged(path, "cut short inside its chunk table")
        for k, offset in enumerate(np.frombuffer(table, "<u8")):
            if offset + 8 > size:
                raise damaged(path, f"cut short: chunk {k} of {chunks} lies past the end of the file")
            f.seek(int(offset))
            y, length = np.frombuffer(f.read(8), "<i4")
            if y != y0 + k * per or length < 0 or offset + 8 + length > size:
                raise damaged(path, f"chunk {k} of {chunks} is cut short or overwritten (scanline {y}, {length} bytes)")


def _parse_header(head: bytes, path: Path) -> tuple[tuple[int, int, int, int], int, int]:
    """(dataWindow, compression id, offset of the chunk table) from the bytes of a header."""
    pos, window, compression = 8, None, None
    while True:
        if pos >= len(head):
            raise damaged(path, "truncated header")
        if head[pos] == 0:
            pos += 1
            break
        try:
            name_end = head.index(b"\0", pos, pos + 256)
            type_end = head.index(b"\0", name_end + 1, name_end + 257)
        except ValueError:
            raise damaged(path, "unreadable header attribute") from None
        name = head[pos:name_end]
        length = int.from_bytes(head[type_end + 1:type_end + 5], "little", signed=True)
        value = head[type_end + 5:type_end + 5 + length]
        if length < 0 or len(value) < length:
            raise damaged(path, "truncated header")
        if name == b"dataWindow" and length == 16:
            window = tuple(int(v) for v in np.frombuffer(value, "<i4"))
        elif name == b"compression" and length == 1:
            compression = value[0]
        pos = type_end + 5 + length
    if window is None or compression is None:
        raise damaged(path, "header lacks dataWindow or compression")
    return window, compression, pos
