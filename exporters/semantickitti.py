"""One sensor's LiDAR sweeps over one trajectory in the SemanticKITTI layout
(``<trajectory>/lidar/<SENSOR>/``, :func:`scan_folder`), written by :class:`ScanWriter` /
:func:`write_scans` and read back exactly by :func:`read_scan` / :func:`read_scans`.

Layout (scan k = the sweep of :attr:`Scan.index` k, file ``NNNNNN`` = k on 6 digits, line k
of every text file; every binary file little-endian, one row per return, in firing order):

- ``velodyne/NNNNNN.bin``: float32 (x, y, z, intensity): the raw, skewed ``Scan.xyz`` (metres,
  sensor frame at each return's time) and ``Scan.intensity`` (0..1): what KITTI's tools read
  with ``np.fromfile(f, dtype=np.float32).reshape(-1, 4)`` (pykitti.utils.load_velo_scan);
- ``velodyne_deskewed/NNNNNN.bin``: the same with ``Scan.xyz_deskewed`` (the scene frozen at
  the sweep's start, moving objects included, in the sensor frame then: world =
  world_from_sensor @ p);
- ``velodyne_exact/NNNNNN.bin``: the same with ``Scan.xyz_exact`` (ground truth: the surface
  point each beam met, without the range noise), for sweeps that keep it (``exact`` in
  lidar.json);
- ``labels/NNNNNN.label``: uint32 ``label | instance << 16`` as SemanticKITTI: the class id
  (``label & 0xFFFF``, an index into ``labels.yaml``) and the object id (``label >> 16``, the
  ``instance`` modality's id); ids >= 65536 are refused;
- ``times/NNNNNN.bin`` float32 seconds after the sweep's start; ``rings/NNNNNN.bin`` uint16
  beam index (0 = lowest beam); ``changes/NNNNNN.bin`` int8 change status
  (exporters.changes.STATUS), only for a sweep whose ``Scan.change`` is set;
- ``poses.txt``: per scan, the first 3 rows of a 4x4 pose, row-major, 12 repr-exact floats.
  KITTI odometry's poses.txt holds the left camera's pose relative to the first one, and its
  calib.txt's ``Tr`` maps velodyne to that camera (SemanticKITTI's tools use
  ``Tr^-1 @ pose @ Tr``). There is no camera here: the "camera" of these poses is the LiDAR
  itself, so ``Tr`` is the identity and line k is ``inverse(world_from_sensor_0) @
  world_from_sensor_k`` (the sensor frame at sweep k's start in the sensor frame at sweep
  0's start; line 0 is exactly the identity): a point p of ``velodyne_deskewed`` k is at
  ``pose_k @ p`` in the first scan's frame. The absolute ``world_from_sensor`` of every
  sweep is in ``lidar.json`` (world = ``world_from_sensor_0 @ pose_k @ p``). The inverse and
  the product are BLAS-free (generator.geometry.camera): the same bytes on every CPU;
- ``calib.txt``: KITTI's five 3x4 lines: ``P0``..``P3`` = [I | 0] (placeholders: no camera in
  this folder; an identity projection rather than zeros, so that pykitti's odometry loader,
  which divides by P[0, 0], reads the file) and ``Tr`` = [I | 0] (see poses.txt);
- ``times.txt``: per scan, its start time in seconds on the trajectory's clock (repr-exact);
- ``labels.yaml``: the class table in semantic-kitti.yaml's keys: ``name``, ``labels`` {id:
  name}, ``color_map`` {id: [b, g, r]} (BGR, as semantic-kitti.yaml's, 0-255), identity
  ``learning_map`` / ``learning_map_inv``, ``learning_ignore`` all false (no ``content``);
- ``lidar.json`` (written last: a folder without it is incomplete): ``format_version``,
  ``sensor`` (its name), ``sensor_summary`` (the sensor's parameters, as the caller gives
  them), ``conventions``, ``files``, ``classes`` and per scan ``index``, ``start_time_s``,
  ``world_from_sensor`` (4x4 nested lists, exact floats), ``returns`` (count), ``change``
  (whether ``changes/`` holds it), ``motion_bound_m`` (metres: no return is further from
  where its surface was at the return's time; null when not given).

Every file is written whole through a temporary file renamed into place. Readers check each
file against the seed's manifest (exporters.jsonfile.read_checked_bytes) and report a missing,
truncated, inconsistent or other-version file as one :class:`DamagedFileError` line.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from generator.geometry.camera import affine_inverse, matmul_exact
from generator.lidar.returns import Scan

from . import FORMAT_VERSION
from .hdf5 import REMEDY, DamagedFileError, access_error
from .jsonfile import check_format_version, read_checked_bytes, read_json_file

LIDAR_FOLDER = "lidar"
LIDAR_JSON = "lidar.json"
LABELS_YAML = "labels.yaml"
DIGITS = 6
ID_LIMIT = 1 << 16  # class and object ids share a uint32: 16 bits each
# per-return files: folder -> (extension, little-endian dtype, columns)
PER_RETURN = {"velodyne": (".bin", "<f4", 4), "velodyne_deskewed": (".bin", "<f4", 4),
              "velodyne_exact": (".bin", "<f4", 4), "labels": (".label", "<u4", 1),
              "times": (".bin", "<f4", 1), "rings": (".bin", "<u2", 1), "changes": (".bin", "<i1", 1)}
CONVENTIONS = {
    "sensor_frame": "KITTI Velodyne: x forward, y left, z up, metres, origin at the optical centre",
    "velodyne": "float32 x, y, z, intensity (0..1): raw returns, each in the sensor frame at its own time (skewed)",
    "velodyne_deskewed": "float32 x, y, z, intensity: the scene frozen at the sweep's start, sensor frame then",
    "velodyne_exact": "float32 x, y, z, intensity: velodyne_deskewed without the range noise (ground truth), where kept",
    "labels": "uint32 class_id | object_id << 16 (SemanticKITTI); class ids index labels.yaml",
    "times": "float32 seconds after the sweep's start_time_s", "rings": "uint16 beam index, 0 = lowest beam",
    "changes": "int8 change status since the previous stage (exporters.changes.STATUS), only where set",
    "poses.txt": "inverse(world_from_sensor_0) @ world_from_sensor_k, first 3 rows row-major (KITTI odometry with "
                 "the LiDAR as the camera: calib.txt's Tr is the identity)",
    "world_from_sensor": "4x4, the sensor's pose at the sweep's start (world: Z up, metres)",
    "times.txt": "each sweep's start_time_s: seconds on the trajectory's clock (0 at its first frame)",
    "color_map": "BGR 0-255, as semantic-kitti.yaml",
}


def scan_folder(trajectory_folder: str | Path, sensor: str) -> Path:
    """The folder of ``sensor``'s scans in a trajectory's folder: ``<trajectory>/lidar/<sensor>``."""
    if not sensor or sensor in (".", "..") or "/" in sensor or "\\" in sensor:
        raise ValueError(f"sensor name {sensor!r} cannot name a folder: use letters, digits, '-' or '_'")
    return Path(trajectory_folder) / LIDAR_FOLDER / sensor


def scan_file(kind: str, index: int) -> str:
    """The path of scan ``index``'s ``kind`` file (a key of :data:`PER_RETURN`), relative to the folder."""
    return f"{kind}/{index:0{DIGITS}d}{PER_RETURN[kind][0]}"


def write_whole(path: Path, data: bytes) -> None:
    """``data`` written to ``path`` through a temporary file beside it renamed into place (never
    a half-written file under the real name; the temporary file is removed whatever fails)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


def _fit(scan: Scan, name: str, dtype: str, top: int | None = None, why: str = "") -> np.ndarray:
    """``scan.<name>`` as ``dtype``; integers outside the dtype's range (or above ``top``, for
    the reason ``why``) are refused with one line."""
    values = np.asarray(getattr(scan, name))
    info = np.iinfo(dtype) if np.dtype(dtype).kind in "iu" else None
    if info is not None:
        if values.dtype.kind not in "iu":
            raise ValueError(f"scan {scan.index}: {name} holds {values.dtype} values, not integers")
        top = info.max if top is None else min(top, info.max)
        if values.size and (values.min() < info.min or values.max() > top):
            bad = int(values.max()) if values.max() > top else int(values.min())
            raise ValueError(f"scan {scan.index}: {name} {bad} is out of range {info.min}..{top}{why}")
    return values.astype(dtype)


def per_return_arrays(scan: Scan, classes: int) -> dict[str, np.ndarray]:
    """The per-return files' arrays of ``scan`` (keys of :data:`PER_RETURN`; ``changes`` only when set);
    class ids must be < ``classes`` (the table's length) and both ids < 65536."""
    n = len(scan)
    intensity = _fit(scan, "intensity", "<f4")
    out = {}
    for kind, name in (("velodyne", "xyz"), ("velodyne_deskewed", "xyz_deskewed"), ("velodyne_exact", "xyz_exact")):
        if getattr(scan, name) is None:
            continue
        rows = np.empty((n, 4), "<f4")
        rows[:, :3], rows[:, 3] = _fit(scan, name, "<f4").reshape(n, 3), intensity
        out[kind] = rows
    label = _fit(scan, "label", "<u4", min(classes, ID_LIMIT) - 1,
                 f" (class ids index the table of {classes} classes; SemanticKITTI keeps 16 bits per id)")
    instance = _fit(scan, "instance", "<u4", ID_LIMIT - 1, " (SemanticKITTI keeps 16 bits per id)")
    out["labels"] = label | (instance << np.uint32(16))
    out["times"], out["rings"] = _fit(scan, "time", "<f4"), _fit(scan, "ring", "<u2")
    if scan.change is not None:
        out["changes"] = _fit(scan, "change", "<i1")
    return out


def relative_pose(first: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``inverse(first) @ pose`` (4x4, float64), BLAS-free: the same bits on every CPU."""
    return matmul_exact(affine_inverse(first), pose)


def _matrix_line(m: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in np.asarray(m, np.float64)[:3].ravel())


def calib_text() -> str:
    """calib.txt: P0..P3 and Tr as [I | 0] (no camera; the poses are the LiDAR's: module docstring)."""
    eye = " ".join(f"{v:.12e}" for v in np.eye(3, 4).ravel())
    return "".join(f"{key}: {eye}\n" for key in ("P0", "P1", "P2", "P3", "Tr"))


def labels_table(classes: list[str], colours: list[tuple[int, int, int]]) -> dict:
    """semantic-kitti.yaml's keys for our taxonomy: names, BGR colours, identity learning maps."""
    if len(classes) != len(colours):
        raise ValueError(f"{len(classes)} classes but {len(colours)} colours")
    ids = range(len(classes))
    return {"name": "buildee-sites",
            "labels": {i: str(classes[i]) for i in ids},
            "color_map": {i: [int(c) for c in reversed(tuple(colours[i]))] for i in ids},  # RGB -> BGR
            "learning_map": {i: i for i in ids}, "learning_map_inv": {i: i for i in ids},
            "learning_ignore": {i: False for i in ids}}


class ScanWriter:
    """Writes one sensor's sweeps into ``folder`` (new or empty) as they come: :meth:`add` writes
    a sweep's per-return files, :meth:`close` the per-trajectory ones (poses.txt, times.txt,
    calib.txt, labels.yaml, lidar.json last). ``sensor_summary``: the sensor's parameters (JSON
    values); ``classes``/``colours``: the taxonomy (names, RGB 0-255), class id = position."""

    def __init__(self, folder: str | Path, sensor_summary: dict, classes: list[str],
                 colours: list[tuple[int, int, int]]):
        self.folder = Path(folder)
        if self.folder.exists() and (not self.folder.is_dir() or any(self.folder.iterdir())):
            raise ValueError(f"{self.folder}: already exists and is not an empty folder; write the scans into a new one")
        self.table = labels_table(classes, colours)
        self.summary, self.classes = dict(sensor_summary), [str(c) for c in classes]
        self.sensor: str | None = None
        self.rows: list[dict] = []
        self.poses: list[np.ndarray] = []
        self.written: list[str] = []
        self.folder.mkdir(parents=True, exist_ok=True)

    def add(self, scan: Scan, motion_bound_m: float | None = None) -> None:
        """Write ``scan``'s per-return files; scans come in order of index, from 0, one sensor.
        ``motion_bound_m``: the sweep's motion bound (generator/lidar/scanner.py ``Sweep``),
        recorded in lidar.json."""
        if scan.index != len(self.rows):
            raise ValueError(f"scan index {scan.index}: expected {len(self.rows)} (scans come in order, from 0)")
        if self.sensor not in (None, scan.sensor):
            raise ValueError(f"scan {scan.index} is sensor {scan.sensor!r}'s, this folder holds {self.sensor!r}'s")
        pose = np.asarray(scan.world_from_sensor, np.float64)
        if pose.shape != (4, 4) or not np.isfinite(pose).all():
            raise ValueError(f"scan {scan.index}: world_from_sensor must be a finite 4x4 matrix, not {pose.shape}")
        arrays = per_return_arrays(scan, len(self.classes))
        for kind, values in arrays.items():
            self._write(scan_file(kind, scan.index), values.tobytes())
        self.sensor = scan.sensor
        self.poses.append(pose)
        self.rows.append({"index": int(scan.index), "start_time_s": float(scan.start_time_s),
                          "world_from_sensor": pose.tolist(), "returns": len(scan), "change": "changes" in arrays,
                          "exact": "velodyne_exact" in arrays,
                          "motion_bound_m": None if motion_bound_m is None else float(motion_bound_m)})

    def close(self) -> list[Path]:
        """Write the per-trajectory files; returns every file written (absolute paths, in order)."""
        import yaml

        rel = [np.eye(4)] + [relative_pose(self.poses[0], p) for p in self.poses[1:]]
        self._write("poses.txt", "".join(_matrix_line(m) + "\n" for m in rel[:len(self.poses)]).encode())
        self._write("times.txt", "".join(f"{r['start_time_s']!r}\n" for r in self.rows).encode())
        self._write("calib.txt", calib_text().encode())
        self._write(LABELS_YAML, yaml.safe_dump(self.table, sort_keys=False).encode())
        doc = {"format_version": FORMAT_VERSION, "sensor": self.sensor, "sensor_summary": self.summary,
               "conventions": CONVENTIONS, "files": {k: f"{k}/NNNNNN{v[0]}" for k, v in PER_RETURN.items()},
               "classes": self.classes, "scans": self.rows}
        try:
            text = json.dumps(doc, indent=1, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{self.folder / LIDAR_JSON}: sensor_summary is not plain JSON ({exc})") from None
        self._write(LIDAR_JSON, text.encode())
        return [self.folder.absolute() / r for r in self.written]

    def _write(self, rel: str, data: bytes) -> None:
        path = self.folder / rel
        path.parent.mkdir(exist_ok=True)
        write_whole(path, data)
        self.written.append(rel)


def write_scans(folder: str | Path, scans: list[Scan], sensor_summary: dict, classes: list[str],
                colours: list[tuple[int, int, int]]) -> list[Path]:
    """Write ``scans`` (one sensor's, indices 0..K-1 in order) into ``folder`` (:class:`ScanWriter`);
    returns every file written, absolute paths."""
    writer = ScanWriter(folder, sensor_summary, classes, colours)
    for scan in scans:
        writer.add(scan)
    return writer.close()


def write_scan_changes(folder: str | Path, changes: list[np.ndarray]) -> list[Path]:
    """Add each scan's change status (int8 per return, exporters.changes.STATUS codes) to the
    finished scan folder ``folder`` (a timeline's stage k > 0, once its changes are known):
    ``changes/NNNNNN.bin`` per scan, then lidar.json again with ``change`` true (written last,
    as before). Returns the files written (absolute paths)."""
    folder = Path(folder)
    doc = json.loads((folder / LIDAR_JSON).read_text())
    if len(changes) != len(doc["scans"]):
        raise ValueError(f"{folder}: {len(changes)} change arrays for {len(doc['scans'])} scans")
    written = []
    for row, change in zip(doc["scans"], changes):
        change = np.asarray(change)
        if change.shape != (row["returns"],) or change.dtype.kind not in "iu":
            raise ValueError(f"{folder}: scan {row['index']}: change needs {row['returns']} integer values, got "
                             f"{change.shape} {change.dtype}")
        path = folder / scan_file("changes", row["index"])
        path.parent.mkdir(exist_ok=True)
        write_whole(path, change.astype("<i1").tobytes())
        row["change"] = True
        written.append(path.absolute())
    write_whole(folder / LIDAR_JSON, json.dumps(doc, indent=1, allow_nan=False).encode())
    return written + [(folder / LIDAR_JSON).absolute()]


def read_lidar_json(folder: str | Path) -> dict:
    """``folder``'s lidar.json, checked: its format version and its keys (DamagedFileError
    otherwise); each row of ``scans`` has its ``world_from_sensor`` as a (4, 4) float64 array."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DamagedFileError(f"{folder}: no such folder of LiDAR scans; {REMEDY}")
    path = folder / LIDAR_JSON
    doc = read_json_file(path, "LiDAR scan index")
    check_format_version(path, doc.get("format_version") if isinstance(doc, dict) else None)
    try:
        for row in doc["scans"]:
            row["index"], row["returns"], row["change"] = int(row["index"]), int(row["returns"]), bool(row["change"])
            row["start_time_s"] = float(row["start_time_s"])
            row["world_from_sensor"] = np.array(row["world_from_sensor"], np.float64).reshape(4, 4)
        if not (isinstance(doc["sensor_summary"], dict) and isinstance(doc["classes"], list)
                and isinstance(doc["sensor"], str)):
            raise TypeError("sensor, sensor_summary or classes of the wrong type")
    except (KeyError, TypeError, ValueError) as exc:
        raise DamagedFileError(f"{path}: not a lidar.json of this format ({exc.__class__.__name__}: {exc}); "
                               f"{REMEDY}") from None
    if [row["index"] for row in doc["scans"]] != list(range(len(doc["scans"]))):
        raise DamagedFileError(f"{path}: its scans are not numbered 0..{len(doc['scans']) - 1}; {REMEDY}")
    return doc


def read_bytes(path: Path) -> bytes:
    """``path``'s bytes, checked against the seed's manifest; a missing or unreadable file is one
    DamagedFileError (or AccessError) line."""
    try:
        return read_checked_bytes(path)
    except FileNotFoundError:
        raise DamagedFileError(f"{path}: no such file; {REMEDY}") from None
    except OSError as exc:
        raise access_error(exc, path) or DamagedFileError(f"{path}: unreadable ({exc.strerror}); {REMEDY}") from None


def read_array(folder: Path, kind: str, index: int, returns: int) -> np.ndarray:
    """Scan ``index``'s ``kind`` file as a native-endian array ((N, 4) or (N,)), checked to hold
    ``returns`` whole rows."""
    path = folder / scan_file(kind, index)
    _, dtype, columns = PER_RETURN[kind]
    row = np.dtype(dtype).itemsize * columns
    data = read_bytes(path)
    if len(data) % row:
        raise DamagedFileError(f"{path}: truncated ({len(data)} bytes, not a multiple of {row}); {REMEDY}")
    if len(data) // row != returns:
        raise DamagedFileError(f"{path}: holds {len(data) // row} returns, lidar.json says {returns}; {REMEDY}")
    values = np.frombuffer(data, dtype).astype(np.dtype(dtype).newbyteorder("="))
    return values.reshape(-1, columns) if columns > 1 else values


def read_scan(folder: str | Path, index: int, doc: dict | None = None) -> Scan:
    """Scan ``index`` of ``folder`` as written, bit for bit (``doc``: its :func:`read_lidar_json`,
    read when not given)."""
    folder = Path(folder)
    doc = read_lidar_json(folder) if doc is None else doc
    if not 0 <= index < len(doc["scans"]):
        raise ValueError(f"{folder}: holds scans 0..{len(doc['scans']) - 1}, not scan {index}")
    row = doc["scans"][index]
    n = row["returns"]
    raw, deskewed = (read_array(folder, kind, index, n) for kind in ("velodyne", "velodyne_deskewed"))
    label = read_array(folder, "labels", index, n)
    return Scan(sensor=str(doc["sensor"]), index=index, start_time_s=row["start_time_s"],
                world_from_sensor=row["world_from_sensor"], xyz=raw[:, :3].copy(), xyz_deskewed=deskewed[:, :3].copy(),
                intensity=raw[:, 3].copy(), ring=read_array(folder, "rings", index, n),
                time=read_array(folder, "times", index, n), label=(label & 0xFFFF).astype(np.uint16),
                instance=(label >> 16).astype(np.uint16),
                change=read_array(folder, "changes", index, n) if row["change"] else None,
                xyz_exact=read_array(folder, "velodyne_exact", index, n)[:, :3].copy() if row.get("exact") else None)


def read_scans(folder: str | Path) -> list[Scan]:
    """Every scan of ``folder``, in order (:func:`read_scan`)."""
    doc = read_lidar_json(folder)
    return [read_scan(folder, k, doc) for k in range(len(doc["scans"]))]
