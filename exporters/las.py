"""One LiDAR sweep as a LAS 1.4 file (laspy), for tools of terrestrial scanning (CloudCompare,
PDAL, LAStools): :func:`write_las` and its reader :func:`read_las`.

Point format 6 (LAS 1.4, with GPS time), one point per return in firing order:

- x, y, z: the return's WORLD position (``Scan.world_points()``: the de-skewed point carried
  by the sweep's reference pose; metres, the site frame, Z up; no CRS: a site-local frame),
  stored as int32 with scale 0.0001 m and an offset at the sensor's origin rounded to the
  metre: a read-back point lies within 5e-5 m (half of 0.1 mm) of the float64 world point;
- ``intensity``: uint16 round(intensity * 65535) (intensity 0..1, quantised to 1/65535);
- ``classification``: our class id itself (generator/scene/taxonomy.py), a user-defined value,
  not ASPRS's standard classes (ASPRS gives 0..22 meanings such as 2 = ground: ignore them
  here); LAS 1.4's classification holds 8 bits, so an id above 255 is stored as 255 there;
  the extra dimension ``label`` (uint16) carries every id exactly;
- extra dimensions (laspy ExtraBytes): ``label`` (uint16 class id), ``instance`` (uint16
  object id, the ``instance`` modality's), ``ring`` (uint16 beam index, 0 = lowest), and
  ``change`` (int8, exporters.changes.STATUS) when the sweep has one;
- ``gps_time``: seconds, ``(start_time_s + time) + gps_time_offset_s`` in float64 (the
  trajectory's clock plus the caller's offset; the header's GPS time type stays "GPS week
  time": these are not satellite times unless the offset makes them so);
- ``point_source_id``: the sweep's index; return_number = number_of_returns = 1;
- header: system identifier and generating software "buildee-sites", creation date fixed at
  :data:`CREATION_DATE` (the same sweep gives the same bytes; the file's mtime says when);
  a VLR (user_id "buildee", record_id 1) holds JSON: ``format_version``, ``classes`` (the
  class table, id = position), ``sensor``, ``index``, ``start_time_s``, ``world_from_sensor``
  (4x4, exact floats), ``gps_time_offset_s``, ``conventions``.

The file is written whole through a temporary file renamed into place; the reader checks it
against the seed's manifest and reports a missing, damaged or other-version file as one
:class:`DamagedFileError` line. laspy is imported on first use.
"""

from __future__ import annotations

import io
import json
from datetime import date
from pathlib import Path

import numpy as np

from generator.lidar.returns import Scan

from . import FORMAT_VERSION
from .hdf5 import REMEDY, DamagedFileError, damaged, reason
from .jsonfile import check_format_version
from .semantickitti import read_bytes, write_whole

SCALE = 1e-4  # metres per LAS coordinate unit (0.1 mm)
SIGNATURE = "buildee-sites"
VLR_USER, VLR_RECORD = "buildee", 1
CREATION_DATE = date(1970, 1, 1)  # fixed: a file's bytes depend on its scan only
CONVENTIONS = ("x, y, z: world metres (Z up, site frame, no CRS), scale 0.0001, offset = sensor origin rounded to "
               "1 m; intensity = round(i * 65535); classification = class id (user-defined, not ASPRS; 255 = id "
               "above 255) and label = class id; gps_time = (start_time_s + time) + gps_time_offset_s seconds; "
               "point_source_id = sweep index")
EXTRA = (("label", np.uint16, "class id (table: VLR buildee/1)"), ("instance", np.uint16, "object id"),
         ("ring", np.uint16, "beam index, 0 = lowest"))


def _header(scan: Scan, offset: np.ndarray, metadata: dict):
    import laspy

    header = laspy.LasHeader(point_format=6, version="1.4")
    header.system_identifier = header.generating_software = SIGNATURE
    header.creation_date = CREATION_DATE
    header.offsets, header.scales = offset, np.full(3, SCALE)
    extra = EXTRA + ((("change", np.int8, "change status (changes.STATUS)"),) if scan.change is not None else ())
    header.add_extra_dims([laspy.ExtraBytesParams(name=n, type=t, description=d) for n, t, d in extra])
    header.vlrs.append(laspy.VLR(user_id=VLR_USER, record_id=VLR_RECORD, description="buildee-sites scan",
                                 record_data=json.dumps(metadata).encode()))
    return header


def _ids(values, top: int, what: str) -> np.ndarray:
    values = np.asarray(values)
    if values.dtype.kind not in "iu" or (values.size and (values.min() < 0 or values.max() > top)):
        raise ValueError(f"{what} must be integers in 0..{top}")
    return values.astype(np.uint16)


def write_las(path: str | Path, scan: Scan, classes: list[str], gps_time_offset_s: float = 0.0) -> Path:
    """Write ``scan`` to ``path`` as LAS 1.4 point format 6 (module docstring); ``classes``: the
    class table (id = position). Returns ``path``."""
    import laspy

    path = Path(path)
    label = _ids(scan.label, min(len(classes), 1 << 16) - 1, f"scan {scan.index}: class ids (a {len(classes)}-class table)")
    instance = _ids(scan.instance, 65535, f"scan {scan.index}: object ids")
    ring = _ids(scan.ring, 65535, f"scan {scan.index}: ring indices")
    intensity = np.asarray(scan.intensity, np.float64)
    if intensity.size and not (intensity.min() >= 0 and intensity.max() <= 1):
        raise ValueError(f"scan {scan.index}: intensity must lie in 0..1 (NaN neither)")
    pose = np.asarray(scan.world_from_sensor, np.float64)
    world, offset = scan.world_points(), np.round(pose[:3, 3])
    if world.size and not (np.isfinite(world).all() and np.abs(world - offset).max() < (2**31 - 1) * SCALE):
        raise ValueError(f"scan {scan.index}: a return lies beyond +-214 km of the sensor (LAS int32 coordinates)")
    metadata = {"format_version": FORMAT_VERSION, "classes": [str(c) for c in classes], "sensor": scan.sensor,
                "index": int(scan.index), "start_time_s": float(scan.start_time_s), "world_from_sensor": pose.tolist(),
                "gps_time_offset_s": float(gps_time_offset_s), "conventions": CONVENTIONS}
    las = laspy.LasData(_header(scan, offset, metadata))
    las.x, las.y, las.z = world[:, 0], world[:, 1], world[:, 2]
    las.intensity = np.round(intensity * 65535).astype(np.uint16)
    las.classification = np.minimum(label, 255).astype(np.uint8)
    las.return_number, las.number_of_returns = np.ones(len(scan), np.uint8), np.ones(len(scan), np.uint8)
    las.gps_time = (float(scan.start_time_s) + np.asarray(scan.time, np.float64)) + float(gps_time_offset_s)
    las.point_source_id = np.full(len(scan), _ids([scan.index], 65535, f"scan index {scan.index}: scan indices")[0], np.uint16)
    las.label, las.instance, las.ring = label, instance, ring
    if scan.change is not None:
        las.change = np.asarray(scan.change, np.int8)
    buffer = io.BytesIO()
    las.write(buffer)
    write_whole(path, buffer.getvalue())
    return path


def read_las(path: str | Path) -> dict:
    """A file of :func:`write_las`: ``xyz`` (N, 3) float64 world metres (quantised to 0.1 mm),
    ``intensity`` (N,) float32 0..1 (the stored uint16 / 65535), ``classification`` (N,) uint8,
    ``label``, ``instance``, ``ring``, ``point_source_id`` (N,) uint16, ``gps_time`` (N,)
    float64 seconds, ``change`` (N,) int8 or None, and ``metadata`` (the VLR's JSON, its
    ``world_from_sensor`` a (4, 4) array)."""
    import laspy

    path = Path(path)
    try:
        las = laspy.read(io.BytesIO(read_bytes(path)))
        vlr = next((v for v in las.header.vlrs if v.user_id == VLR_USER and v.record_id == VLR_RECORD), None)
        if vlr is None:
            raise DamagedFileError(f"{path}: a LAS file without buildee-sites' VLR ({VLR_USER}/{VLR_RECORD}); {REMEDY}")
        metadata = json.loads(vlr.record_data)
        check_format_version(path, metadata.get("format_version") if isinstance(metadata, dict) else None)
        metadata["world_from_sensor"] = np.array(metadata["world_from_sensor"], np.float64).reshape(4, 4)
    except DamagedFileError:
        raise
    except (laspy.LaspyException, ValueError, KeyError, TypeError, EOFError) as exc:
        raise damaged(path, f"unreadable LAS: {reason(exc)}") from None
    names = set(las.point_format.dimension_names)
    if not {"label", "instance", "ring"} <= names:
        raise DamagedFileError(f"{path}: lacks the extra dimensions label, instance and ring; {REMEDY}")
    return {"xyz": np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)]),
            "intensity": (np.asarray(las.intensity) / 65535).astype(np.float32),
            "classification": np.asarray(las.classification, np.uint8),
            "label": np.asarray(las.label, np.uint16), "instance": np.asarray(las.instance, np.uint16),
            "ring": np.asarray(las.ring, np.uint16), "point_source_id": np.asarray(las.point_source_id, np.uint16),
            "gps_time": np.asarray(las.gps_time, np.float64),
            "change": np.asarray(las.change, np.int8) if "change" in names else None, "metadata": metadata}
