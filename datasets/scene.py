"""One generated seed folder, read lazily with no bpy (formats: docs/format.md).

Files are opened when they are read and closed straight after (HDF5 files are kept open
per process and reopened after a fork), so a :class:`Scene` can be handed to DataLoader
worker processes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from exporters import FORMAT_VERSION, VERSION_REMEDY
from exporters.frames import FrameReader, frame_names
from exporters.hdf5 import H5_ERRORS, DamagedFileError, access_error, damaged, reason
from exporters.jsonfile import read_checked_bytes
from exporters.manifest import read_manifest, stage_count, timeline_stage
from exporters.tracks import TrackReader
from generator.batch.rig import flown_kinds, rig_of_config

SUPPORTED_VERSIONS = (FORMAT_VERSION,)


class DatasetError(ValueError):
    """A folder that cannot be read as a generated scene, or a damaged file in it (the
    message names the file and says what to do)."""


class MissingKeyError(KeyError):
    """A KeyError whose message prints as written (a plain KeyError prints its repr, quotes and
    escapes included)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


def _checked(call, *args, path=None):
    """``call(*args)``, with a damaged file, or one this process cannot open now (too many
    open files, no permission: not damage), reported as a :class:`DatasetError`."""
    try:
        return call(*args)
    except DamagedFileError as exc:
        raise DatasetError(str(exc)) from None
    except DatasetError:
        raise
    except H5_ERRORS as exc:  # damaged HDF5 metadata can fail anywhere h5py looks
        cause = access_error(exc)
        if cause is None and path is None:
            raise
        raise DatasetError(str(cause or damaged(path, reason(exc)))) from None


def _written_with_instance(path: Path) -> None:
    """coco.json and boxes3d.json exist only where the ``instance`` output was written: say so
    when a seed made without it is asked for annotations."""
    if path.exists():
        return
    config = (read_manifest(path.parent.parent) or {}).get("config")
    outputs = config.get("outputs") if isinstance(config, dict) else None
    if outputs and "instance" not in outputs:
        raise DatasetError(f"{path.parent.parent}: made with --outputs {','.join(outputs)}, without instance, so it has "
                           f"no {path.name}; regenerate it with instance in --outputs to get annotations")


def seed_fields(manifest: dict, folder: Path) -> tuple[int, list[str]]:
    """(seed, trajectory kinds) of a seed's manifest, checked: a format version this reader
    does not read, or a manifest without them, is a :class:`DatasetError` naming the file."""
    version = manifest.get("format_version")
    if version not in SUPPORTED_VERSIONS:
        raise DatasetError(f"{folder}: format_version {version!r}; this reader reads "
                           f"{', '.join(SUPPORTED_VERSIONS)} ({VERSION_REMEDY})")
    try:
        config = manifest["config"]
        seed, kinds = int(manifest["seed"]), flown_kinds(config["trajectories"], rig_of_config(config))
    except (KeyError, TypeError, ValueError):
        raise DatasetError(f"{folder / 'manifest.json'}: damaged manifest (no seed or trajectories); "
                           "regenerate this seed with python -m generator") from None
    if any(Path(k).name != k or k in ("", ".", "..") for k in kinds):
        raise DatasetError(f"{folder / 'manifest.json'}: damaged manifest (trajectory names "
                           f"{kinds} are not folder names); regenerate this seed")
    return seed, kinds


def read_labels(folder: Path) -> list[str]:
    """The label table (``labels.json``) of a seed folder or of a timeline's stage, checked: a
    missing or unreadable file is a :class:`DatasetError` naming it."""
    path = folder / "labels.json"
    if not path.is_file():
        raise DatasetError(f"{path}: missing; the seed folder is incomplete, regenerate it")
    try:
        labels = json.loads(read_checked_bytes(path).decode("utf-8"))
    except DamagedFileError as exc:
        raise DatasetError(str(exc)) from None
    except (OSError, ValueError) as exc:
        raise DatasetError(str(access_error(exc, path) or f"{path}: unreadable label table ({exc.__class__.__name__}); "
                               "regenerate this seed with python -m generator")) from None
    if not isinstance(labels, list) or not all(isinstance(n, str) for n in labels):
        raise DatasetError(f"{path}: not a JSON list of class names; regenerate this seed")
    return labels


def check_index(i, n: int, what: str) -> int:
    """Python indexing (negative counts from the end) with a message stating the valid range."""
    if isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)):
        raise TypeError(f"{what} index must be an integer, got {type(i).__name__}")
    j = int(i) + n if i < 0 else int(i)
    if not 0 <= j < n:
        raise IndexError(f"{what} index {int(i)} out of range: valid indices are -{n}..{n - 1}" if n
                         else f"{what} index {int(i)} out of range: there are no frames")
    return j


def read_point_cloud(folder: str | Path, static_only: bool = False) -> dict:
    """The labelled ground-truth cloud of a seed folder (or of one stage ``SEED/phase_K`` of a
    timeline seed), read from its ``ground_truth/points.ply`` (written by exporters/ground_truth.py):
    xyz (N, 3) float32 metres, label, instance (N,) int32, dynamic (N,) bool (objects at the
    first animation frame); ``static_only`` keeps the points that are not dynamic. A missing
    or damaged file, one of another format version or one lacking a property of
    ``exporters.ground_truth.POINT_PROPERTIES`` (checked by ``exporters.ground_truth.read_points``)
    raises a :class:`DatasetError` naming the file."""
    from exporters.ground_truth import GroundTruthError, read_points

    path = Path(folder) / "ground_truth" / "points.ply"
    if not path.is_file():
        manifest = read_manifest(Path(folder)) if Path(folder).is_dir() else None
        if manifest is not None and stage_count(manifest) > 1:
            raise DatasetError(f"{folder}: a timeline seed of {stage_count(manifest)} stages (--phases): each stage "
                               f"has its cloud; read one with read_point_cloud('{Path(folder) / 'phase_0'}')")
        raise DatasetError(f"{path}: missing; the seed folder is incomplete, regenerate it")
    try:
        d = read_points(path.parent)
    except GroundTruthError as exc:
        raise DatasetError(str(exc)) from None
    out = {"xyz": np.stack([d.vertex[c] for c in "xyz"], 1), "label": d.vertex["label"],
           "instance": d.vertex["instance"], "dynamic": d.vertex["dynamic"].astype(bool)}
    if static_only:
        keep = ~out["dynamic"]
        out = {k: v[keep] for k, v in out.items()}
    return out


@dataclass
class Frame:
    """One rendered frame, exactly as stored, keyed by modality name (exporters/modalities.py):
    ``frame.depth`` or ``frame["depth"]``. ``rgb`` (H, W, 3) float32 display sRGB in [0, 1]
    (the 8-bit PNG / 255); ``rgb_linear`` (H, W, 3) float16 scene-linear; ``depth`` (H, W)
    float32 planar metres (+inf: no surface); ``label``, ``instance`` (H, W) int32 (-1: none);
    ``normal`` (H, W, 3) float32 world unit normals facing the camera (0: none); ``flow``,
    ``backward_flow`` (H, W, 2) float32 pixels to the next / previous frame (NaN: none).
    ``K`` (3, 3); ``pose`` (4, 4) OpenCV world_from_camera; ``timestamp`` seconds."""

    outputs: dict
    K: np.ndarray
    pose: np.ndarray
    timestamp: float
    index: int
    trajectory: str

    def __getattr__(self, name: str):
        outputs = self.__dict__.get("outputs")
        if outputs is not None and name in outputs:
            return outputs[name]
        raise AttributeError(f"frame has no {name!r}" + (f" (modalities read: {', '.join(outputs)})" if outputs else ""))

    def __getitem__(self, name: str):
        """A modality, or one of the camera fields (``K``, ``pose``, ``timestamp``, ``index``,
        ``trajectory``); KeyError naming what the frame holds otherwise."""
        if name in self.outputs:
            return self.outputs[name]
        if name in ("K", "pose", "timestamp", "index", "trajectory"):
            return getattr(self, name)
        read = f"{', '.join(self.outputs)} (modalities read)" if self.outputs else "no modalities (none read)"
        raise MissingKeyError(f"frame has no {name!r}; it holds {read} and K, pose, timestamp, index, trajectory")

    def as_dict(self) -> dict:
        return dict(self.outputs) | {"K": self.K, "pose": self.pose, "timestamp": self.timestamp,
                                     "index": self.index, "trajectory": self.trajectory}


class Sequence:
    """The frames of one trajectory of a scene: ``len``, ``seq[i]`` -> :class:`Frame`,
    ``seq[a:b]`` -> list, plus the point tracks of ``tracks.h5``."""

    def __init__(self, folder: Path, labels: list[str]):
        self.folder, self.kind, self.labels = folder, folder.name, labels
        for name in ("tracks.h5", "trajectory.npz"):
            if not (folder / name).is_file():
                raise DatasetError(f"{folder}: missing {name}; the seed folder is incomplete, regenerate it")
        self.tracks = _checked(TrackReader, folder / "tracks.h5")  # the one reader of tracks.h5 (exporters/tracks.py)
        t = self.tracks
        self.K, self.width, self.height, self.poses, self.timestamps = t.K, t.width, t.height, t.poses, t.timestamps
        self.lens = t.lens  # the cameras' lens model (generator/geometry/lens.py; the ideal pinhole by default)
        self._frames = _checked(FrameReader, folder)
        # what the camera's sensor did to rgb (generator/image_sensor.py; ideal by default) and
        # its linear gain per frame (exposure)
        self.image_sensor, self.exposure_gain = self._frames.image_sensor, self._frames.exposure_gain
        # seconds from the first row's time to the last's (0: a global shutter; docs/cameras.md):
        # row r shows the scene at timestamps[t] + ((r + 1) / height - 1/2) x readout_s
        self.readout_s = self._frames.readout_s
        self._rolling = None  # the rows' motion (generator/geometry/rolling.py), made on first use
        if (self._frames.width, self._frames.height) != (self.width, self.height):
            raise DatasetError(f"{folder / 'frames.json'}: frames of {self._frames.width}x{self._frames.height} "
                               f"pixels, cameras of {self.width}x{self.height}; regenerate this seed with python -m generator")

    @property
    def modalities(self) -> tuple[str, ...]:
        """Names of the per-frame modalities stored for this trajectory (frames.json)."""
        return self._frames.modalities

    def __len__(self) -> int:
        return len(self.poses)

    def exr_path(self, i: int) -> Path:
        return self.folder / frame_names(i)[0]

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        return self.read(i)

    def read(self, i: int, keys=None) -> Frame:
        """Frame ``i`` (Python indexing) with the modalities ``keys`` (default: all stored)."""
        i = check_index(i, len(self), f"{self.kind} frame")
        try:
            outputs = _checked(self._frames.read, i, keys)
        except KeyError as exc:
            raise MissingKeyError(exc.args[0]) from None
        return Frame(outputs, self.K.copy(), self.poses[i].copy(), float(self.timestamps[i]), i, self.kind)

    def visible_tracks(self, t: int) -> dict:
        """Points visible at frame t (Python indexing: -1 is the last frame): ``ids`` (n,),
        ``xy`` (n, 2) pixels, ``depth`` (n,) metres."""
        t = check_index(t, len(self), f"{self.kind} frame")
        return _checked(self.tracks.visible, t)

    def point_positions(self, t: int, ids: np.ndarray) -> np.ndarray:
        """World positions (n, 3) float64 metres of points ``ids`` at frame t (Python indexing;
        dynamic ones moved); no ids (``[]``) give a (0, 3) array."""
        t = check_index(t, len(self), f"{self.kind} frame")
        ids = np.asarray(ids)
        n = len(self.points["label"])
        if not ids.size:
            ids = ids.astype(np.int64)  # numpy reads [] as float64: no ids, (0, 3) positions
        elif ids.dtype.kind not in "iu" or ids.min() < 0 or ids.max() >= n:
            raise IndexError(f"point ids must be integers in 0..{n - 1}")
        return _checked(self.tracks.positions, t, ids)

    def project_points(self, t: int, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where points ``ids`` land in frame t's image: (pixels (n, 2) as (x, y), planar depth
        (n,)), through the lens and, on a rolling-shutter seed, at the row that sees each one
        (generator/geometry/rolling.py; NaN where no row sees it once), as tracks.h5 stores
        the visible ones."""
        from generator.geometry.camera import project

        xyz = self.point_positions(t, ids)
        if self.readout_s == 0:
            return project(xyz, self.poses[t], self.K, self.lens)
        from generator.geometry.rolling import RollingCamera, RollingShutter

        if self._rolling is None:
            self._rolling = RollingCamera(RollingShutter(self.readout_s, self.height), self.timestamps, self.poses,
                                          self.object_matrices)
        ids = np.asarray(ids, np.int64)
        return self._rolling.project(t, self.points["local"][ids], self.points["dynamic_object"][ids], self.K,
                                     self.lens)

    @cached_property
    def points(self) -> dict:
        """The tracked surface points: local (N, 3), label, instance, dynamic_object (N,)."""
        return _checked(lambda: self.tracks.points)

    @cached_property
    def object_matrices(self) -> np.ndarray:
        """(T, D, 4, 4) world_from_object of the moving objects."""
        return _checked(lambda: self.tracks.object_matrices)

    @cached_property
    def coverage(self) -> np.ndarray:
        """(T,) share of surface points observed at least once after each frame."""
        return _checked(lambda: self.tracks.coverage)

    @cached_property
    def coco(self):
        """The trajectory's instance masks and 2D boxes (``coco.json``, :class:`exporters.coco.CocoReader`)."""
        from exporters.coco import CocoReader

        _written_with_instance(self.folder / "coco.json")
        return _checked(CocoReader, self.folder / "coco.json")

    @cached_property
    def boxes3d(self):
        """The trajectory's 3D boxes (``boxes3d.json``, :class:`exporters.boxes3d.Boxes3DReader`)."""
        from exporters.boxes3d import Boxes3DReader

        _written_with_instance(self.folder / "boxes3d.json")
        return _checked(Boxes3DReader, self.folder / "boxes3d.json")

    def check_annotations(self) -> None:
        """The DatasetError :meth:`annotations` would raise for a seed made without the
        instance output (so without coco.json and boxes3d.json), raised now."""
        for name in ("coco.json", "boxes3d.json"):
            _written_with_instance(self.folder / name)

    def annotations(self, t: int) -> dict:
        """The objects in frame t (Python indexing): ``boxes2d`` (from coco.json: ``instance_id``,
        ``label``, ``category_id``, ``area`` (n,), ``bbox`` and ``amodal_bbox`` (n, 4) as
        (x0, y0, x1, y1) pixel edges; instance k's mask is ``frame.instance == instance_id[k]``)
        and ``boxes3d`` (``instance``, ``label``, ``pixels``, ``pixel_share`` (n,), ``centre``,
        ``size`` (n, 3) metres, ``rotation`` (n, 3, 3) world_from_box). docs/format.md."""
        t = check_index(t, len(self), f"{self.kind} frame")
        return {"boxes2d": _checked(self.coco.frame, t), "boxes3d": _checked(self.boxes3d.frame, t)}

    @cached_property
    def tapvid(self) -> dict:
        """TAP-Vid query subset: query_points (Q, 3) (t, y, x), tracks (Q, T, 2) (x, y),
        occluded (Q, T), tracks_3d (Q, T, 3), point_ids (Q,) (checked for consistency)."""
        return _checked(self.tracks.tapvid)


class Scene:
    """Everything one seed folder holds, read lazily.

    ``scene.labels`` the label table; ``scene.trajectories`` the kinds; ``scene[kind]`` a
    :class:`Sequence`; ``scene.frames`` all frames of all trajectories (index or slice);
    ``scene.point_cloud()`` the labelled ground-truth cloud; ``scene.manifest``.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.is_dir():
            raise DatasetError(f"{self.path}: " + ("a file, not a seed folder; pass the folder that holds it"
                                                   if self.path.exists() else "no such folder"))
        manifest = read_manifest(self.path)
        stage = timeline_stage(self.path) if manifest is None else None
        if stage is not None:
            raise DatasetError(f"{self.path}: stage {stage[1]} of the timeline seed {stage[0]}; read it with "
                               f"datasets.change.Timeline('{stage[0]}').sequence({stage[1]}, kind)")
        if manifest is None:
            raise DatasetError(f"{self.path}: not a complete seed folder (no readable manifest.json); "
                               "point at output/seed_NNNNNN written by python -m generator")
        if stage_count(manifest) > 1:
            raise DatasetError(f"{self.path}: a timeline seed of {stage_count(manifest)} stages (--phases); read it "
                               f"with datasets.change.Timeline('{self.path}')")
        self.manifest = manifest
        self.seed, self.trajectories = seed_fields(manifest, self.path)
        self.labels: list[str] = read_labels(self.path)
        self._sequences: dict[str, Sequence] = {}

    def __repr__(self) -> str:
        return f"Scene(seed={self.seed}, trajectories={self.trajectories}, frames={len(self.frames)})"

    def __getitem__(self, kind: str) -> Sequence:
        if kind not in self.trajectories:
            raise MissingKeyError(f"no trajectory {kind!r} in {self.path} (has {', '.join(self.trajectories)})")
        if kind not in self._sequences:
            self._sequences[kind] = Sequence(self.path / kind, self.labels)
        return self._sequences[kind]

    @property
    def sequences(self) -> list[Sequence]:
        return [self[k] for k in self.trajectories]

    @cached_property
    def frames(self) -> "_Frames":
        return _Frames(self.sequences)

    def point_cloud(self, static_only: bool = False) -> dict:
        """The labelled ground-truth cloud of this seed (:func:`read_point_cloud`)."""
        return read_point_cloud(self.path, static_only)

    def disparity(self, camera: str, i: int) -> np.ndarray:
        """Ground-truth disparity (H, W) float32 pixels of frame ``i`` of a rectified pair: the
        left image is the reference trajectory's, the right one the rig camera ``camera`` (a
        folder such as ``orbit_right``, whose extrinsics move it B metres along x: ``--stereo
        B``). A surface point at planar depth Z in the left image is fx B / Z pixels further
        left in the right one; 0 where the left pixel sees no surface (docs/cameras.md)."""
        rig = rig_of_config(self.manifest["config"])
        pairs = {} if rig is None else {f"{kind}_{name}": (kind, rig.baseline(k))
                                        for kind in self.manifest["config"]["trajectories"]
                                        for k, name in enumerate(rig.names)}
        if pairs.get(camera, (None, None))[1] is None:
            rectified = [c for c, (_, b) in pairs.items() if b is not None]
            raise DatasetError(f"{camera!r} is not the right camera of a rectified pair in {self.path} (those are: "
                               f"{', '.join(rectified) or 'none; make one with --stereo B'})")
        kind, baseline = pairs[camera]
        left = self[kind]
        if not left.lens.ideal:
            raise DatasetError(f"{camera!r} and {kind!r} see through a {left.lens.model} lens: a pair is rectified only "
                               "with the pinhole (undistort and rectify it first)")
        depth = np.asarray(left.read(i, ["depth"])["depth"], np.float64)
        with np.errstate(divide="ignore"):
            return np.where(np.isfinite(depth), left.K[0, 0] * baseline / depth, 0.0).astype(np.float32)


class _Frames:
    """All frames of several sequences as one list (index or slice)."""

    def __init__(self, sequences: list[Sequence]):
        self.sequences = sequences
        self.starts = np.cumsum([0] + [len(s) for s in sequences])

    def __len__(self) -> int:
        return int(self.starts[-1])

    def locate(self, i: int) -> tuple[Sequence, int]:
        i = check_index(i, len(self), "frame")
        k = int(np.searchsorted(self.starts, i, side="right") - 1)
        return self.sequences[k], i - int(self.starts[k])

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        seq, j = self.locate(i)
        return seq[j]
