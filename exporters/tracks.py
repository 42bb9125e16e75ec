"""Per-trajectory point tracks in HDF5 (``tracks.h5``), readable with plain h5py.

Layout (all lengths in metres, pixels as (x, y) with the top-left pixel's centre at
(0.5, 0.5), poses OpenCV world_from_camera); every dataset states its unit in its ``units``
attribute (:data:`UNITS`), the root attributes restate the conventions.

  /cameras    width, height (attrs); lens (attr, JSON, only for a distorting lens: Lens.as_dict);
              K (3, 3); world_from_camera (T, 4, 4); timestamps (T,) s
  /points     local (N, 3) float64: world coordinates for static points, object frame for
              dynamic ones; label (N,) int32; instance (N,) int32; dynamic_object (N,) int32
              (index into /objects, -1 = static)
  /objects    names (D,) of the dynamic objects; world_from_object (T, D, 4, 4)
  /visibility offsets (T + 1,) int64: frame t's visible points are index[offsets[t]:offsets[t+1]];
              index (M,) int32; xy (M, 2) float32 pixel positions; depth (M,) float32 planar depth
  /dynamic    positions (T, Nd, 3) float32 world positions of the dynamic points (ids in point_ids)
  /coverage   (T,) share of all points observed at least once after each frame
  /tapvid     query_points (Q, 3) (t, y, x); tracks (Q, T, 2) (x, y); occluded (Q, T) bool;
              tracks_3d (Q, T, 3) world metres; point_ids (Q,)
  attrs       format_version, labels (JSON, fixed-length UTF-8), conventions

The ``tracks`` sink (:class:`TracksSink`) writes it as the trajectory is flown.

Every dataset carries HDF5's Fletcher-32 checksum and the file uses the HDF5 1.10 format
(checksummed metadata), so a damaged file fails to read instead of giving other values
(exporters/hdf5.py); ``objects/names`` holds fixed-length UTF-8 bytes for the same reason.

:class:`TrackReader` is the one reader of this schema (datasets, evaluation and tests use it).
"""

from __future__ import annotations

import json
import os
from functools import cached_property
from pathlib import Path

import h5py
import numpy as np

from generator.geometry.camera import apply_affine, project
from generator.geometry.lens import PINHOLE, Lens

from . import FORMAT_VERSION, VERSION_REMEDY
from .hdf5 import (CHECKSUM, H5_ERRORS, DamagedFileError, access_error, attribute, create_file, damaged, dataset, group,
                   open_file, read, reason, text, text_attribute, verify)
from .sinks import FrameRecord, TrajectoryContext, register_sink

_CHUNK = 1 << 16

# the ``units`` attribute of every dataset (and of the cameras group, for its width/height)
UNITS = {
    "cameras": "width, height: pixels",
    "cameras/K": "pixels: [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], OpenCV, top-left pixel centre (0.5, 0.5); "
                 "distortion: the cameras group's lens attribute (none: a pinhole)",
    "cameras/world_from_camera": "4x4 rigid, translation in metres; OpenCV camera axes (x right, y down, z forward)",
    "cameras/timestamps": "seconds from the first frame",
    "points/local": "metres; world frame for static points, object frame for dynamic points",
    "points/label": "label id (index into the labels attribute), -1 = unlabelled",
    "points/instance": "object id (index into the object table, as the instance maps)",
    "points/dynamic_object": "index into objects/names, -1 = static point",
    "objects/names": "object names (UTF-8)",
    "objects/world_from_object": "4x4, translation in metres",
    "visibility/offsets": "indices into visibility/index: frame t is [offsets[t], offsets[t + 1])",
    "visibility/index": "point ids",
    "visibility/xy": "pixels (x, y), top-left pixel centre (0.5, 0.5)",
    "visibility/depth": "metres, planar depth (camera z)",
    "dynamic/point_ids": "point ids",
    "dynamic/positions": "metres, world frame",
    "coverage": "share of all points observed at least once after each frame, 0..1",
    "tapvid/query_points": "(t, y, x): frame index, pixels",
    "tapvid/tracks": "pixels (x, y), top-left pixel centre (0.5, 0.5)",
    "tapvid/occluded": "True = not visible",
    "tapvid/tracks_3d": "metres, world frame",
    "tapvid/point_ids": "point ids",
}


def _write_units(f: h5py.File, prefix: str = "") -> None:
    for name, unit in UNITS.items():
        if name.startswith(prefix) and name in f:
            f[name].attrs["units"] = text_attribute(unit)


def _append(ds, values) -> None:
    values = np.asarray(values)
    n = ds.shape[0]
    ds.resize(n + len(values), axis=0)
    ds[n:] = values


class TrackWriter:
    """Streams one trajectory's tracks to ``path`` frame by frame; :meth:`close` adds the
    TAP-Vid query subset."""

    def __init__(self, path: str | Path, table: dict, dynamic_names: list[str], labels: list[str],
                 K: np.ndarray, width: int, height: int, queries: int = 256, seed: int = 0, lens: Lens = PINHOLE,
                 projector=None):
        self.path = Path(path)
        # projector(t, ids, world) -> (xy, depth): where points land in frame t's image (default:
        # through K and the lens at the frame's pose; a rolling shutter's: TrajectoryContext.project_points)
        self.projector = projector
        self.f = create_file(self.path)  # checksummed: a flipped byte fails on read (exporters/hdf5.py)
        self.table, self.queries, self.seed = table, queries, seed
        self.K, self.width, self.height, self.lens = np.asarray(K, float), int(width), int(height), lens
        f = self.f
        f.attrs.update({"format_version": FORMAT_VERSION, "labels": text_attribute(json.dumps(labels)),
                        "conventions": "metres; OpenCV camera (x right, y down, z forward); poses world_from_camera; "
                                       "pixels (x, y), top-left pixel centre (0.5, 0.5); depth = planar z"})
        cams = f.create_group("cameras")
        cams.attrs.update({"width": self.width, "height": self.height})
        if not lens.ideal:  # generator/geometry/lens.py Lens.as_dict; absent: the ideal pinhole
            cams.attrs["lens"] = text_attribute(json.dumps(lens.as_dict()))
        dataset(cams, "K", self.K)
        cams.create_dataset("world_from_camera", (0, 4, 4), maxshape=(None, 4, 4), dtype="f8", chunks=(64, 4, 4), **CHECKSUM)
        cams.create_dataset("timestamps", (0,), maxshape=(None,), dtype="f8", chunks=(1024,), **CHECKSUM)
        pts = f.create_group("points")
        opts = {"compression": "gzip", "compression_opts": 4, "shuffle": True}
        for name, dtype in (("local", "f8"), ("label", "i4"), ("instance", "i4"), ("dynamic_object", "i4")):
            key = {"label": "labels"}.get(name, name)
            dataset(pts, name, np.asarray(table[key], dtype=dtype), **opts)
        obj = f.create_group("objects")
        dataset(obj, "names", np.array(dynamic_names, dtype=object))  # fixed-length UTF-8 bytes
        d = len(dynamic_names)
        obj.create_dataset("world_from_object", (0, d, 4, 4), maxshape=(None, d or None, 4, 4), dtype="f8",  # d = 0: no objects
                           chunks=(16, max(d, 1), 4, 4), **CHECKSUM)
        vis = f.create_group("visibility")
        dataset(vis, "offsets", np.zeros(1, np.int64), maxshape=(None,), chunks=(1024,))
        vis.create_dataset("index", (0,), maxshape=(None,), dtype="i4", chunks=(_CHUNK,), **opts, **CHECKSUM)
        vis.create_dataset("xy", (0, 2), maxshape=(None, 2), dtype="f4", chunks=(_CHUNK, 2), **opts, **CHECKSUM)
        vis.create_dataset("depth", (0,), maxshape=(None,), dtype="f4", chunks=(_CHUNK,), **opts, **CHECKSUM)
        self.dyn_ids = np.flatnonzero(np.asarray(table["dynamic_object"]) >= 0).astype(np.int32)
        dyn = f.create_group("dynamic")
        dataset(dyn, "point_ids", self.dyn_ids)
        dyn.create_dataset("positions", (0, len(self.dyn_ids), 3), maxshape=(None, len(self.dyn_ids) or None, 3), dtype="f4",
                           chunks=(1, max(len(self.dyn_ids), 1), 3), **opts, **CHECKSUM)
        f.create_dataset("coverage", (0,), maxshape=(None,), dtype="f8", chunks=(1024,), **CHECKSUM)
        _write_units(f)

    def add_frame(self, timestamp: float, world_from_camera: np.ndarray, world_points: np.ndarray,
                  visible: np.ndarray, object_matrices: np.ndarray, coverage: float) -> None:
        f = self.f
        _append(f["cameras/world_from_camera"], world_from_camera[None])
        _append(f["cameras/timestamps"], [timestamp])
        idx = np.flatnonzero(visible).astype(np.int32)
        if self.projector is not None:
            xy, z = self.projector(len(f["cameras/timestamps"]) - 1, idx, world_points[idx])
        else:
            xy, z = project(world_points[idx], world_from_camera, self.K, self.lens)
        _append(f["visibility/index"], idx)
        _append(f["visibility/xy"], xy.astype(np.float32))
        _append(f["visibility/depth"], z.astype(np.float32))
        _append(f["visibility/offsets"], [f["visibility/offsets"][-1] + len(idx)])
        _append(f["objects/world_from_object"], np.asarray(object_matrices, float)[None])
        _append(f["dynamic/positions"], world_points[self.dyn_ids].astype(np.float32)[None])
        _append(f["coverage"], [coverage])

    def close(self) -> Path:
        """Add the TAP-Vid subset (points visible at least once, seeded choice) and close."""
        f = self.f
        data = read_tracks_file(f)
        T, N = len(data["world_from_camera"]), len(data["label"])
        first = np.full(N, -1, dtype=np.int64)
        for t in range(T - 1, -1, -1):
            first[data["index"][data["offsets"][t]:data["offsets"][t + 1]]] = t
        candidates = np.flatnonzero(first >= 0)
        rng = np.random.default_rng(self.seed)
        ids = np.sort(rng.choice(candidates, size=min(self.queries, len(candidates)), replace=False)) if len(candidates) else np.zeros(0, int)
        tracks, occluded, tracks_3d = np.zeros((len(ids), T, 2)), np.ones((len(ids), T), bool), np.zeros((len(ids), T, 3))
        for t in range(T):
            pos = world_positions(data, t, ids)
            if self.projector is not None:
                tracks[:, t], _ = self.projector(t, ids, pos)
            else:
                tracks[:, t], _ = project(pos, data["world_from_camera"][t], data["K"], self.lens)
            tracks_3d[:, t] = pos
            vis_t = data["index"][data["offsets"][t]:data["offsets"][t + 1]]
            occluded[:, t] = ~np.isin(ids, vis_t)
        # a rolling shutter may find no row that sees a point once (NaN): not visible there
        occluded |= ~np.isfinite(tracks).all(axis=2)
        seen = (~occluded).any(axis=1)
        ids, tracks, occluded, tracks_3d = ids[seen], tracks[seen], occluded[seen], tracks_3d[seen]
        q_t = np.argmax(~occluded, axis=1)  # the first frame that sees each point
        q_xy = tracks[np.arange(len(ids)), q_t]
        g = f.create_group("tapvid")
        g.attrs["conventions"] = "TAP-Vid: query_points (t, y, x); tracks (x, y) pixels; occluded True = not visible"
        dataset(g, "point_ids", ids.astype(np.int32))
        dataset(g, "query_points", np.column_stack([q_t, q_xy[:, 1], q_xy[:, 0]]).astype(np.float32))
        dataset(g, "tracks", tracks.astype(np.float32))
        dataset(g, "occluded", occluded)
        dataset(g, "tracks_3d", tracks_3d.astype(np.float32))
        _write_units(f, "tapvid/")
        f.close()
        return self.path


@register_sink("tracks")
class TracksSink:
    """``tracks.h5``: every frame's visible points, poses and object matrices (:class:`TrackWriter`)."""

    def __init__(self, c: TrajectoryContext):
        self.writer = TrackWriter(Path(c.folder) / "tracks.h5", c.point_table, c.dynamic_objects, c.labels, c.K,
                                  c.width, c.height, seed=c.seed, lens=c.lens,
                                  projector=c.project_points if c.rolling is not None else None)

    def add_frame(self, frame: FrameRecord) -> None:
        self.writer.add_frame(frame.timestamp, frame.world_from_camera, frame.points, frame.visible,
                              frame.object_matrices, frame.coverage)

    def close(self) -> None:
        self.writer.close()


def world_positions(data: dict, t: int, ids: np.ndarray) -> np.ndarray:
    """World positions (n, 3) of points ``ids`` at frame t (dynamic ones moved by their object)."""
    local = data["local"][ids]
    obj = data["dynamic_object"][ids]
    out = local.copy()
    for d in np.unique(obj[obj >= 0]):
        m = data["world_from_object"][t, d]
        sel = obj == d
        out[sel] = apply_affine(m, local[sel])
    return out


_ARRAYS = {"K": "cameras/K", "world_from_camera": "cameras/world_from_camera", "timestamps": "cameras/timestamps",
           "local": "points/local", "label": "points/label", "instance": "points/instance",
           "dynamic_object": "points/dynamic_object", "world_from_object": "objects/world_from_object",
           "offsets": "visibility/offsets", "index": "visibility/index", "xy": "visibility/xy",
           "depth": "visibility/depth", "coverage": "coverage"}


def read_tracks_file(f: h5py.File) -> dict:
    """The arrays of an open tracks.h5 (checked: a damaged dataset raises DamagedFileError)."""
    return {key: read(f, name) for key, name in _ARRAYS.items()}


def check_tracks(data: dict, path) -> None:
    """Shapes and indices that must agree in any intact tracks.h5 (a cheap guard, also for
    files written before the checksums); raises :class:`DamagedFileError`."""
    T, N = len(data["world_from_camera"]), len(data["local"])
    off, index = data["offsets"], data["index"]
    problems = [
        (data["K"].shape != (3, 3) or not np.isfinite(data["K"]).all() or data["K"][0, 0] <= 0 or data["K"][1, 1] <= 0,
         "cameras/K is not a valid intrinsic matrix"),
        (data["world_from_camera"].shape[1:] != (4, 4) or len(data["timestamps"]) != T, "camera arrays disagree"),
        (any(len(data[k]) != N for k in ("label", "instance", "dynamic_object")), "point arrays disagree"),
        (len(off) != T + 1 or off[0] != 0 or np.any(np.diff(off) < 0) or off[-1] != len(index), "visibility offsets"),
        (len(data["xy"]) != len(index) or len(data["depth"]) != len(index), "visibility arrays disagree"),
        (len(index) and (index.min() < 0 or index.max() >= N), "visibility index outside the points"),
    ]
    for bad, what in problems:
        if bad:
            raise damaged(path, what)


def read_tracks(path: str | Path) -> dict:
    """Everything in a tracks.h5 as numpy arrays (plus 'tapvid', 'labels' and 'units');
    :meth:`TrackReader.read_all`."""
    reader = TrackReader(path)
    try:
        return reader.read_all()
    finally:
        reader.close()


def _version_error(path: Path, version) -> DamagedFileError:
    return DamagedFileError(f"{path}: format_version {version!r}; this reader reads {FORMAT_VERSION} ({VERSION_REMEDY})")


class TrackReader:
    """One ``tracks.h5``, read lazily: the file is opened at the first read of a dataset, once
    per process (and reopened after a fork, so a reader can be handed to DataLoader workers).

    On construction the format version and the camera arrays are read and checked, and the
    file is closed again (many readers hold no file open): ``K`` (3, 3), ``width``, ``height``
    (pixels), ``poses`` (T, 4, 4) world_from_camera, ``timestamps`` (T,) s, ``offsets``
    (T + 1,), ``labels``, ``units`` (dataset -> unit). Every failure (damaged file, checksum,
    other version, inconsistent arrays) raises :class:`DamagedFileError` naming the file and
    the remedy; a file this process cannot open (too many open files, no permission)
    raises :class:`~exporters.hdf5.AccessError`."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._file, self._pid = None, None
        try:
            self._guard(self._read_header)
        finally:
            self.close()

    def _guard(self, call, *args):
        try:
            return call(*args)
        except DamagedFileError:
            raise
        except H5_ERRORS as exc:  # damaged metadata can fail anywhere h5py looks
            raise access_error(exc, self.path) or damaged(self.path, reason(exc)) from None

    def file(self) -> h5py.File:
        """The open file (this process's handle)."""
        if self._file is None or self._pid != os.getpid():
            self._file, self._pid = open_file(self.path), os.getpid()
        return self._file

    def close(self) -> None:
        if self._file is not None and self._pid == os.getpid():
            self._file.close()
        self._file = None

    def __enter__(self) -> "TrackReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __getstate__(self):
        return self.__dict__ | {"_file": None, "_pid": None}

    def read(self, key: str, sel=()) -> np.ndarray:
        """Dataset ``key`` (e.g. ``"visibility/xy"``), optionally a selection of it."""
        return self._guard(lambda: read(self.file(), key, self.path, sel))

    def _read_header(self) -> None:
        f = self.file()
        version = text(attribute(f, "format_version")) if "format_version" in f.attrs else None
        if version != FORMAT_VERSION:
            raise _version_error(self.path, version)
        if "cameras" not in f and "visibility" not in f:  # another of our files (same format version)
            raise DamagedFileError(f"{self.path}: not a tracks.h5 (its top level holds {', '.join(sorted(f)) or 'nothing'}); "
                                   "give a trajectory's tracks.h5 (seed_NNNNNN/TRAJECTORY/tracks.h5)")
        cams = group(f, "cameras", self.path)
        self.width, self.height = (int(attribute(cams, k, self.path)) for k in ("width", "height"))
        self.K, self.poses = read(f, "cameras/K"), read(f, "cameras/world_from_camera")
        self.lens = PINHOLE
        if "lens" in cams.attrs:
            try:
                self.lens = Lens.from_dict(json.loads(text(attribute(cams, "lens"))))
            except (ValueError, TypeError) as exc:
                raise damaged(self.path, f"attribute cameras/lens: {exc}") from None
        self.timestamps, self.offsets = read(f, "cameras/timestamps"), read(f, "visibility/offsets")
        try:
            self.labels = json.loads(text(attribute(f, "labels")))
        except ValueError as exc:
            raise damaged(self.path, f"attribute labels: {exc.__class__.__name__}") from None
        self.units = {}
        f.visititems(lambda name, obj: self.units.__setitem__(name, text(obj.attrs["units"])) if "units" in obj.attrs else None)
        T = len(self.poses)
        problems = [
            (self.K.shape != (3, 3) or not np.isfinite(self.K).all() or self.K[0, 0] <= 0 or self.K[1, 1] <= 0,
             "cameras/K is not a valid intrinsic matrix"),
            (self.width <= 0 or self.height <= 0, "camera size"),
            (self.poses.shape[1:] != (4, 4) or not np.isfinite(self.poses).all(), "cameras/world_from_camera"),
            (self.timestamps.shape != (T,) or not np.isfinite(self.timestamps).all(), "cameras/timestamps"),
            (self.offsets.shape != (T + 1,) or (T and (self.offsets[0] != 0 or np.any(np.diff(self.offsets) < 0))),
             "visibility/offsets"),
        ]
        for bad, what in problems:
            if bad:
                raise damaged(self.path, f"{what} is inconsistent")

    def __len__(self) -> int:
        return len(self.poses)

    def visible(self, t: int) -> dict:
        """Points visible at frame t (0 <= t < T): ``ids`` (n,), ``xy`` (n, 2) pixels, ``depth`` (n,) metres."""
        a, b = int(self.offsets[t]), int(self.offsets[t + 1])
        out = {k: self.read(f"visibility/{name}", np.s_[a:b]) for k, name in (("ids", "index"), ("xy", "xy"), ("depth", "depth"))}
        if any(len(v) != b - a for v in out.values()) or (b > a and (out["ids"].min() < 0 or
                                                                      out["ids"].max() >= len(self.points["label"]))):
            raise damaged(self.path, f"visibility of frame {t} is inconsistent")
        return out

    @cached_property
    def points(self) -> dict:
        """The tracked surface points: ``local`` (N, 3), ``label``, ``instance``, ``dynamic_object`` (N,)."""
        return {k: self.read(f"points/{k}") for k in ("local", "label", "instance", "dynamic_object")}

    @cached_property
    def object_matrices(self) -> np.ndarray:
        """(T, D, 4, 4) world_from_object of the moving objects."""
        return self.read("objects/world_from_object")

    @cached_property
    def coverage(self) -> np.ndarray:
        """(T,) share of all points observed at least once after each frame."""
        return self.read("coverage")

    def positions(self, t: int, ids: np.ndarray) -> np.ndarray:
        """World positions (n, 3) metres of points ``ids`` at frame t (dynamic ones moved)."""
        p = self.points
        return world_positions({"local": p["local"], "dynamic_object": p["dynamic_object"],
                                "world_from_object": self.object_matrices}, t, ids)

    def tapvid(self, verify_checksums: bool = False) -> dict:
        """The TAP-Vid query subset, checked for consistency; with ``verify_checksums`` every
        dataset of the file is read first, so any damage anywhere is refused."""
        def load():
            f = self.file()
            if verify_checksums:
                verify(f, self.path)
            return read_tapvid(f, self.path)

        return self._guard(load)

    def read_all(self) -> dict:
        """Every array of the file (the keys of ``_ARRAYS``, plus ``labels``, ``units``,
        ``dynamic_positions``, ``dynamic_ids`` and ``tapvid`` when present), checked."""
        def load():
            f = self.file()
            data = read_tracks_file(f)
            check_tracks(data, self.path)
            data |= {"labels": self.labels, "units": dict(self.units), "dynamic_positions": read(f, "dynamic/positions"),
                     "dynamic_ids": read(f, "dynamic/point_ids")}
            if "tapvid" in f:
                data["tapvid"] = read_tapvid(f, self.path)
            return data

        return self._guard(load)


TAPVID = ("query_points", "tracks", "occluded", "tracks_3d", "point_ids")


def read_tapvid(f: h5py.File, path) -> dict:
    """The TAP-Vid query subset of an open tracks.h5, checked for consistency (shapes, query
    frames, finite positions, each query visible at its own frame where it was picked)."""
    g = group(f, "tapvid", path)
    tv = {k: read(g, k, path) for k in TAPVID}
    q, T = len(tv["point_ids"]), len(read(f, "cameras/timestamps", path))
    shapes = {"query_points": (q, 3), "tracks": (q, T, 2), "occluded": (q, T), "tracks_3d": (q, T, 3)}
    for k, shape in shapes.items():
        if tv[k].shape != shape:
            raise damaged(path, f"tapvid/{k} has shape {tv[k].shape}, expected {shape}")
    t = tv["query_points"][:, 0]
    if q and (not np.isfinite(tv["query_points"]).all() or np.any(t != np.round(t)) or t.min() < 0 or t.max() >= T):
        raise damaged(path, "tapvid/query_points: query frames outside the trajectory")
    if q:
        ti = t.astype(np.int64)
        at_query = tv["tracks"][np.arange(q), ti]
        if (tv["occluded"][np.arange(q), ti].any() or not np.isfinite(tv["tracks"][~tv["occluded"]]).all()
                or not np.array_equal(at_query[:, ::-1], tv["query_points"][:, 1:])):
            raise damaged(path, "tapvid tracks disagree with their query points")
    return tv
