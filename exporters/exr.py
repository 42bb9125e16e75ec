"""Per-frame EXR files: every EXR-stored modality of one frame (``exporters/modalities.py``).

Layout (docs/format.md): a multi-part scanline OpenEXR file, one part per component type
(readers that take one type per part, like imageio's FreeImage, or only the first part,
like OpenCV, get the colour from part 0):

- ``colour``: HALF ``R``, ``G``, ``B`` scene-linear RGB, with the ``chromaticities`` attribute;
- ``data``: FLOAT ``Z`` planar depth, ``normal.X/Y/Z``, ``flow.X/Y``, ``backward_flow.X/Y``...;
- ``ids``: UINT ``label``, ``instance`` (4294967295 = -1 = none), exact.

Parts with nothing to hold are left out. Header attributes ``buildee/*`` state the
conventions; ``buildee/modalities`` maps each modality to its channels. The reader returns
exactly the arrays that were written, keyed by modality name.
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import numpy as np
import OpenEXR

from .hdf5 import REMEDY, DamagedFileError, damaged
from .modalities import MODALITIES, PART_OF_TYPE

COMPRESSIONS = {
    "none": OpenEXR.NO_COMPRESSION,
    "rle": OpenEXR.RLE_COMPRESSION,
    "zips": OpenEXR.ZIPS_COMPRESSION,
    "zip": OpenEXR.ZIP_COMPRESSION,
    "piz": OpenEXR.PIZ_COMPRESSION,
}
# Blender's working space (linear Rec.709 / sRGB primaries, D65 white): red, green, blue, white xy
REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)
ATTRIBUTES = {
    "buildee/format": "frame-exr-2",
    "buildee/pixels": "pixel (row i, col j) has its centre at (x, y) = (j + 0.5, i + 0.5)",
}
PART_NAMES = tuple(PART_OF_TYPE.values())  # colour (HALF), data (FLOAT), ids (UINT)


def use_all_cores() -> None:
    """Let OpenEXR compress and decompress line blocks on every core this process may use
    (its global thread pool; the library's default is none). The bytes written do not depend
    on the thread count (tested). A count set by the caller (non-zero) is kept. Called by the
    first write or read of a frame, not at import: a process that only imports this module
    starts no pool."""
    with _POOL_LOCK:
        if OpenEXR.global_thread_count() == 0:
            OpenEXR.set_global_thread_count(len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                                            else os.cpu_count() or 1)


_POOL_LOCK = threading.Lock()  # held from before a fork to after it: no thread restarts the pool in between
_POOL_BEFORE_FORK = [0]  # the pool's thread count when this process forked (one fork at a time: the lock)


def _stop_pool_before_fork() -> None:
    """A forked child (a DataLoader worker, a subprocess started with a preexec_fn) would hold
    the pool without its threads: any EXR read there would wait on them forever, and stopping
    that pool in the child joins threads that do not exist there (a crash). So the parent stops
    its pool (joining its own threads) before it forks; the child starts with none and makes
    its own on its first read; the parent gets its pool back after the fork."""
    _POOL_LOCK.acquire()
    _POOL_BEFORE_FORK[0] = OpenEXR.global_thread_count()
    if _POOL_BEFORE_FORK[0]:
        OpenEXR.set_global_thread_count(0)


def _restore_pool_after_fork() -> None:
    if _POOL_BEFORE_FORK[0]:
        OpenEXR.set_global_thread_count(_POOL_BEFORE_FORK[0])
    _POOL_LOCK.release()


def _fresh_lock_in_child() -> None:
    global _POOL_LOCK
    _POOL_LOCK = threading.Lock()  # the parent's is held by the forking thread, which the child lacks


if hasattr(os, "register_at_fork"):
    os.register_at_fork(before=_stop_pool_before_fork, after_in_parent=_restore_pool_after_fork,
                        after_in_child=_fresh_lock_in_child)


def write_frame(path: str | Path, outputs: dict[str, np.ndarray], compression: str = "zip",
                attributes: dict | None = None) -> Path:
    """Write ``outputs`` (modality name -> array, all of one (H, W)) to an EXR file, one part
    per component type: ``colour`` (HALF), ``data`` (FLOAT), ``ids`` (UINT) (docs/format.md)."""
    use_all_cores()
    if compression not in COMPRESSIONS:
        raise ValueError(f"unknown EXR compression {compression!r}; choose one of {', '.join(COMPRESSIONS)}")
    unknown = [n for n in outputs if n not in MODALITIES]
    if unknown:
        raise ValueError(f"unknown modality {', '.join(unknown)}: choose from {', '.join(MODALITIES)}")
    parts: dict[str, dict[str, np.ndarray]] = {}
    layout: dict[str, dict[str, list[str]]] = {}
    for name, array in outputs.items():
        m = MODALITIES[name]
        part = PART_OF_TYPE[m.exr_type]
        channels = parts.setdefault(part, {})
        clash = [c for c in m.channels if c in channels]
        if clash:
            raise ValueError(f"{name} and another output both use EXR channels {clash}; write one of them")
        channels.update(m.encode(array))
        layout.setdefault(part, {})[name] = list(m.channels)
    if not parts:
        raise ValueError("nothing to write: pass at least one output")
    shapes = {c.shape for ch in parts.values() for c in ch.values()}
    if len(shapes) != 1:
        raise ValueError(f"all outputs must share one (H, W), got {sorted(shapes)}")
    extra = {k: v if isinstance(v, str) else json.dumps(v) for k, v in (attributes or {}).items()}
    exr_parts = []
    for part in PART_NAMES:
        if part not in parts:
            continue
        header = {"compression": COMPRESSIONS[compression], "type": OpenEXR.scanlineimage} | ATTRIBUTES | extra
        header["buildee/modalities"] = json.dumps(layout[part])
        for name in layout[part]:
            header[f"buildee/{name}"] = MODALITIES[name].description
        if "rgb_linear" in layout[part]:
            header["chromaticities"] = REC709_CHROMATICITIES
        exr_parts.append(OpenEXR.Part(header, dict(parts[part]), name=part))  # the library replaces the arrays
    path = Path(path)
    with OpenEXR.File(exr_parts) as f:
        f.write(str(path))
    return path


def write_frame_exr(path: str | Path, rgb: np.ndarray | None = None, depth: np.ndarray | None = None,
                    label: np.ndarray | None = None, instance: np.ndarray | None = None, compression: str = "zip",
                    attributes: dict | None = None) -> Path:
    """The four classic outputs by keyword (``rgb`` is display-referred colour, stored as
    modality ``rgb`` in channels R, G, B); see :func:`write_frame`."""
    outputs = {k: v for k, v in (("rgb", rgb), ("depth", depth), ("label", label), ("instance", instance))
               if v is not None}
    return write_frame(path, outputs, compression, attributes)


def read_frame_exr(path: str | Path, keys=None) -> dict:
    """Read a frame EXR: the written arrays keyed by modality name (only those present, or
    those in ``keys``) plus ``header`` (part 0's attributes). Files without
    ``buildee/modalities`` (other tools') are matched against the registry by channel names.
    A truncated or damaged file raises :class:`~exporters.hdf5.DamagedFileError` naming it
    (its structure is checked before OpenEXR decodes it; ZIP chunks carry zlib's checksum)."""
    use_all_cores()
    path = Path(path)
    if not path.is_file():
        raise DamagedFileError(f"{path}: no such file; {REMEDY}")
    parts = check_exr_structure(path)
    out: dict = {}
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            if parts is not None and len(f.parts) != parts:  # OpenEXR drops a part it cannot decode
                raise ValueError(f"{parts - len(f.parts)} of {parts} parts failed to decode")
            for k, part in enumerate(f.parts):
                header = dict(part.header)
                if k == 0:
                    out["header"] = header
                ch = {name: c.pixels for name, c in part.channels.items()}
                for name, m in _modalities_of(header, ch).items():
                    if not all(c in ch for c in m.channels):  # a part whose chunks failed to decode
                        raise ValueError(f"part {k} lacks the channels of {name}")
                    if keys is None or name in keys:
                        out[name] = m.decode(ch)
    except (OSError, ValueError, RuntimeError, TypeError) as exc:
        raise damaged(path, f"OpenEXR cannot decode its pixels: {exc.__class__.__name__}") from None
    return out


def _modalities_of(header: dict, channels: dict) -> dict:
    raw = header.get("buildee/modalities")
    if raw is not None:
        names = list(json.loads(raw))
        unknown = [n for n in names if n not in MODALITIES]
        if unknown:
            raise ValueError(f"modalities {unknown} are not registered in this process")
        return {n: MODALITIES[n] for n in names}
    found = {}
    for name, m in MODALITIES.items():  # a plain file: first registered owner of each channel set
        if m.part is not None and all(c in channels for c in m.channels) and not any(
                set(m.channels) & set(o.channels) for o in found.values()):
            found[name] = m
    return found


# ---- structure check (before OpenEXR decodes anything) ---------------------------------------

_MAGIC = b"\x76\x2f\x31\x01"
_LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}  # by compression id
_TILED_OR_DEEP = 0x200 | 0x800
_MULTI_PART = 0x1000
_MAX_HEADER = 1 << 20


def check_exr_structure(path: Path) -> int | None:
    """Check a scanline EXR (single- or multi-part: our frames) is whole: the headers parse,
    and the chunk tables point at chunks that lie inside the file, each for the part and
    scanlines it should hold. Tiled and deep files are left to OpenEXR (returns None); else
    returns the number of parts. Raises DamagedFileError."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(min(size, _MAX_HEADER))
        if head[:4] != _MAGIC:
            raise damaged(path, "not an OpenEXR file (bad magic number)" if size >= 4 else "empty or truncated file")
        flags = int.from_bytes(head[4:8], "little")
        if flags & _TILED_OR_DEEP:
            return None
        multi = bool(flags & _MULTI_PART)
        headers, pos = [], 8
        while True:
            window, compression, pos = _parse_header(head, pos, path)
            headers.append((window, compression))
            if not multi:
                break
            if pos >= len(head):
                raise damaged(path, "truncated header")
            if head[pos] == 0:
                pos += 1
                break
        counts = []
        for window, compression in headers:
            per = _LINES_PER_CHUNK.get(compression)
            if per is None or window[3] < window[1]:
                raise damaged(path, f"header: compression {compression}, data window {window}")
            counts.append(-(-(window[3] - window[1] + 1) // per))
        f.seek(pos)
        table = f.read(8 * sum(counts))
        if len(table) < 8 * sum(counts):
            raise damaged(path, "cut short inside its chunk table")
        offsets = np.frombuffer(table, "<u8")
        start = 0
        for p, ((window, compression), chunks) in enumerate(zip(headers, counts)):
            per = _LINES_PER_CHUNK[compression]
            for k, offset in enumerate(offsets[start:start + chunks]):
                _check_chunk(f, path, size, int(offset), p if multi else None, window[1] + k * per, k, chunks)
            start += chunks
    return len(headers)


def _check_chunk(f, path: Path, size: int, offset: int, part: int | None, y_expected: int, k: int, chunks: int) -> None:
    prefix = 12 if part is not None else 8
    if offset + prefix > size:
        raise damaged(path, f"cut short: chunk {k} of {chunks} lies past the end of the file")
    f.seek(offset)
    fields = np.frombuffer(f.read(prefix), "<i4")
    if part is not None:
        if fields[0] != part:
            raise damaged(path, f"chunk {k} of part {part} is overwritten (it names part {fields[0]})")
        fields = fields[1:]
    y, length = fields
    if y != y_expected or length < 0 or offset + prefix + length > size:
        raise damaged(path, f"chunk {k} of {chunks} is cut short or overwritten (scanline {y}, {length} bytes)")


def _parse_header(head: bytes, pos: int, path: Path) -> tuple[tuple[int, int, int, int], int, int]:
    """(dataWindow, compression id, offset after the header) of the header starting at ``pos``."""
    window, compression = None, None
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
