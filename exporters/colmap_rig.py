"""A camera rig's joint models (``--rig``, ``--stereo``): ``seed_N/rigs/<kind>/`` holds, for the
trajectory ``kind`` and its rig cameras (generator/batch/rig.py), made from what every camera
wrote into its own folder:

- ``sparse/0``: one COLMAP model (pycolmap; rigs.bin and frames.bin beside the cameras, images
  and points) with one camera per rig camera (the trajectory's own first, then the rig's in
  order), one rig whose reference sensor is the trajectory's camera and whose other sensors
  carry ``sensor_from_rig`` = the inverse of their ``rig_from_camera``, and one frame per
  time step (``rig_from_world`` = the trajectory camera's ``camera_from_world``) holding every
  camera's image; image names are relative to the seed folder (``orbit/rgb_000000.png``,
  ``orbit_right/rgb_000000.png``: give COLMAP the seed folder as its image path); keypoints
  are the exact projections of the static points each camera sees (those of its own
  sparse/0, in the same order), and a 3D point is any static point seen in at least two
  images of the rig, whichever cameras saw it, coloured from the display PNG where first seen
  (frames in order, cameras in rig order); with ``--colmap-text`` also as text;
- ``points3D.ply``: those points with their colours;
- ``transforms.json``: nerfstudio's multi-camera form: every camera's frames, each frame with
  its own camera's intrinsics and distortion fields and ``camera`` (its folder), file paths
  relative to this file; depth paths only when every camera wrote depth in the same unit.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from generator.geometry.camera import invert_rigid, project

from .colmap import UNCOLOURED, write_points_ply
from .nerfstudio import POINTS_PLY, TRANSFORMS
from .tracks import TrackReader

RIGS = "rigs"  # seed_N/rigs/<kind>/
CAMERA_FIELDS = ("camera_model", "fl_x", "fl_y", "cx", "cy", "w", "h", "k1", "k2", "k3", "k4", "p1", "p2")
DEPTH_FIELDS = ("depth_unit_scale_factor", "integer_depth_scale")


def write_rig_models(seed_folder: str | Path, kinds: list[str], rig, text: bool = False) -> list[Path]:
    """For each trajectory of ``kinds`` flown with ``rig``: ``seed_folder/rigs/<kind>/`` (see the
    module's docstring). Returns the folders written."""
    seed_folder = Path(seed_folder)
    out = []
    for kind in kinds:
        folders = [kind] + rig.folders(kind)
        target = seed_folder / RIGS / kind
        write_rig_colmap(seed_folder, folders, rig.rig_from_camera, target, text)
        write_rig_transforms(seed_folder, folders, target)
        out.append(target)
    return out


def _static_world_points(reader: TrackReader) -> tuple[np.ndarray, np.ndarray]:
    """(world positions (N, 3) of the trajectory's points, (N,) bool static): a static
    point's stored coordinates are its world ones."""
    local = reader.read("points/local")
    return local, reader.read("points/dynamic_object") < 0


def write_rig_colmap(seed_folder: Path, folders: list[str], rig_from_camera: np.ndarray, target: Path,
                     text: bool) -> "pycolmap.Reconstruction":  # noqa: F821
    """``target/sparse/0`` and ``target/points3D.ply`` of the rig cameras flown in ``folders``
    (the reference first; ``rig_from_camera`` (C - 1, 4, 4) of the others)."""
    readers = [TrackReader(seed_folder / f / "tracks.h5") for f in folders]
    try:
        return _rig_model(seed_folder, folders, readers, rig_from_camera, target, text)
    finally:
        for reader in readers:
            reader.close()


def _rig_model(seed_folder: Path, folders: list[str], readers: list, rig_from_camera: np.ndarray, target: Path,
               text: bool) -> "pycolmap.Reconstruction":  # noqa: F821
    """:func:`write_rig_colmap` with the cameras' tracks open."""
    import pycolmap

    world, static = _static_world_points(readers[0])
    rec = pycolmap.Reconstruction()
    cameras = []
    for c, r in enumerate(readers):
        model, params = r.lens.colmap_camera(r.K)
        cameras.append(pycolmap.Camera(model=model, width=r.width, height=r.height, params=params, camera_id=c + 1))
        rec.add_camera(cameras[-1])
    rig = pycolmap.Rig(rig_id=1)
    rig.add_ref_sensor(cameras[0].sensor_id)
    for camera, m in zip(cameras[1:], rig_from_camera):
        rig.add_sensor(camera.sensor_id, pycolmap.Rigid3d(invert_rigid(m)[:3, :4]))
    rec.add_rig(rig)
    tracks: dict[int, list] = {}
    colours = _FirstSight(len(world), seed_folder)
    for t in range(len(readers[0].poses)):
        ids = [t * len(readers) + c + 1 for c in range(len(readers))]
        frame = pycolmap.Frame(frame_id=t + 1, rig_id=1,
                               rig_from_world=pycolmap.Rigid3d(invert_rigid(readers[0].poses[t])[:3, :4]))
        for camera, image_id in zip(cameras, ids):
            frame.add_data_id(pycolmap.data_t(camera.sensor_id, image_id))
        rec.add_frame(frame)
        for c, (r, image_id) in enumerate(zip(readers, ids)):
            index = r.read("visibility/index", np.s_[r.offsets[t]:r.offsets[t + 1]]).astype(np.int64)
            seen = index[static[index]]
            uv, _ = project(world[seen], r.poses[t], r.K, r.lens)
            name = f"{folders[c]}/rgb_{t:06d}.png"
            image = pycolmap.Image(name=name, keypoints=np.asarray(uv, np.float64).reshape(-1, 2), camera_id=c + 1,
                                   image_id=image_id)
            image.frame_id = t + 1
            rec.add_image(image)
            for k, p in enumerate(seen):
                tracks.setdefault(int(p), []).append(pycolmap.TrackElement(image_id, k))
            colours.look(name, seen, uv, r.width, r.height)
        rec.register_frame(t + 1)
    kept = [p for p in sorted(tracks) if len(tracks[p]) >= 2]
    for p in kept:
        rec.add_point3D(world[p], pycolmap.Track(tracks[p]), colours.colors[p])
    rec.update_point_3d_errors()
    (target / "sparse" / "0").mkdir(parents=True, exist_ok=True)
    rec.write(str(target / "sparse" / "0"))
    if text:
        rec.write_text(str(target / "sparse" / "0"))
    keep = np.asarray(kept, np.int64)
    write_points_ply(target / POINTS_PLY, world[keep].reshape(-1, 3), colours.colors[keep].reshape(-1, 3))
    return rec


class _FirstSight:
    """Each point's colour: the display PNG's pixel where the point is first seen (UNCOLOURED
    where no rgb PNG was written)."""

    def __init__(self, n: int, seed_folder: Path):
        self.colors = np.tile(np.array(UNCOLOURED, np.uint8), (n, 1))
        self.coloured = np.zeros(n, bool)
        self.seed_folder = seed_folder

    def look(self, name: str, seen: np.ndarray, uv: np.ndarray, width: int, height: int) -> None:
        new = ~self.coloured[seen]
        path = self.seed_folder / name
        if not new.any() or not path.is_file():
            return
        with Image.open(path) as im:
            rgb = np.asarray(im.convert("RGB"))
        px = np.minimum(np.floor(uv[new]).astype(int), [width - 1, height - 1])
        self.colors[seen[new]] = rgb[px[:, 1], px[:, 0]]
        self.coloured[seen[new]] = True


def write_rig_transforms(seed_folder: Path, folders: list[str], target: Path) -> Path:
    """``target/transforms.json``: every camera's transforms.json (from its folder) as one
    multi-camera file (see the module's docstring)."""
    docs = [json.loads((seed_folder / f / TRANSFORMS).read_text()) for f in folders]
    units = {tuple(d.get(k) for k in DEPTH_FIELDS) for d in docs}
    depth = len(units) == 1 and None not in next(iter(units))
    frames = []
    for folder, doc in zip(folders, docs):
        camera = {k: doc[k] for k in CAMERA_FIELDS if k in doc}
        for frame in doc["frames"]:
            entry = dict(frame) | camera | {"camera": folder}
            for key in ("file_path", "depth_file_path", "depth_path"):
                if key in entry:
                    entry[key] = f"../../{folder}/{entry[key]}"
            if not depth:
                entry.pop("depth_file_path", None)
                entry.pop("depth_path", None)
            frames.append(entry)
    head = {k: v for k, v in docs[0].items() if k != "frames" and (depth or k not in DEPTH_FIELDS)}
    head["ply_file_path"] = POINTS_PLY
    path = target / TRANSFORMS
    path.write_text(json.dumps(head | {"frames": frames}, indent=1))
    return path
