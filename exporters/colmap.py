"""COLMAP sparse model of a trajectory (written with pycolmap, read by COLMAP and pycolmap).

One PINHOLE camera; one registered image per frame, named like the PNGs, with pose
``camera_from_world`` (the inverse of our world_from_camera; COLMAP's pixel convention is
ours: the top-left pixel's centre is (0.5, 0.5)); keypoints at the exact projections of the
static surface points visible in that frame; 3D points = static points seen in at least two
frames, with their tracks, the colour of the rendered pixel where first seen, and their
reprojection error (COLMAP's: the mean distance in pixels between a point's projection in
each image of its track and the keypoint there; rounding only, ~1e-14 px, since the keypoints
are exact projections). Dynamic points never enter the model.

:func:`read_colmap_model` reads a model back for scoring, refusing damaged files and
degenerate cameras. The ``colmap`` sink (:class:`ColmapSink`) writes the model of each
trajectory, and ``points3D.ply`` beside it; ``--colmap-text`` adds the model as text.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from generator.cli_args import Option
from generator.geometry.camera import invert_rigid
from generator.geometry.lens import PINHOLE, Lens

from . import FORMAT_VERSION
from .frames import frame_names
from .nerfstudio import POINTS_PLY
from .ply import write_ply
from .sinks import FrameRecord, TrajectoryContext, register_sink

PLY_FORMAT_COMMENT = "buildee format"  # points3D.ply's header comment, followed by the format version
UNCOLOURED = (128, 128, 128)  # COLMAP point colour when no rgb is written


def write_colmap_model(folder: str | Path, K: np.ndarray, width: int, height: int, poses: np.ndarray,
                       image_names: list[str], observations: list[tuple[np.ndarray, np.ndarray]],
                       points: np.ndarray, colors: np.ndarray, text: bool = False,
                       lens: Lens = PINHOLE) -> pycolmap.Reconstruction:
    """Write ``folder`` (binary cameras.bin, images.bin, points3D.bin, rig and frame files;
    plus .txt with ``text``). ``observations[t]`` = (point indices (n,), pixel xy (n, 2)) of
    frame t; ``points`` (N, 3) world metres; ``colors`` (N, 3) uint8; the camera's model is
    that of ``lens`` (PINHOLE, OPENCV, FULL_OPENCV or OPENCV_FISHEYE: Lens.colmap_camera)."""
    import pycolmap  # here, not at the top: the scan of exporters/ imports this module into every run's driver

    rec = pycolmap.Reconstruction()
    model, params = lens.colmap_camera(K)
    camera = pycolmap.Camera(model=model, width=int(width), height=int(height), params=params, camera_id=1)
    rec.add_camera_with_trivial_rig(camera)
    tracks: dict[int, list] = {}
    for t, ((idx, uv), pose, name) in enumerate(zip(observations, poses, image_names)):
        image_id = t + 1
        image = pycolmap.Image(name=name, keypoints=np.asarray(uv, dtype=np.float64).reshape(-1, 2), camera_id=1, image_id=image_id)
        cam_from_world = invert_rigid(pose)[:3, :4]  # BLAS-free: the same bits on every CPU
        rec.add_image_with_trivial_frame(image, pycolmap.Rigid3d(cam_from_world))
        for k, p in enumerate(np.asarray(idx)):
            tracks.setdefault(int(p), []).append(pycolmap.TrackElement(image_id, k))
    for p in sorted(tracks):
        elements = tracks[p]
        if len(elements) >= 2:
            rec.add_point3D(np.asarray(points[p], dtype=np.float64), pycolmap.Track(elements), np.asarray(colors[p], dtype=np.uint8))
    rec.update_point_3d_errors()  # COLMAP's own mean reprojection error per point (add_point3D leaves -1)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rec.write(str(folder))
    if text:
        rec.write_text(str(folder))
    return rec


@register_sink("colmap", options=(Option("--colmap-text", "also write the COLMAP models as text (.txt)",
                                          action="store_true", default=False),))
class ColmapSink:
    """``sparse/0`` (COLMAP model: exact poses, keypoints at the projections of the visible
    static points, 3D points seen in at least two frames, coloured from the display PNG where
    first seen; also as text with ``--colmap-text``) and ``points3D.ply`` (those 3D points with
    their colours, for splatting trainers: transforms.json's ``ply_file_path``)."""

    def __init__(self, context: TrajectoryContext):
        self.context = context
        n = len(context.point_table["local"])
        self.static = np.asarray(context.point_table["dynamic_object"]) < 0
        self.colors = np.tile(np.array(UNCOLOURED, np.uint8), (n, 1))
        self.coloured = np.zeros(n, bool)
        self.observations: list[tuple[np.ndarray, np.ndarray]] = []
        self.points = None

    def add_frame(self, frame: FrameRecord) -> None:
        c = self.context
        seen = np.flatnonzero(frame.visible & self.static)
        uv, _ = c.project_points(frame.index, seen, frame.points[seen])  # through the lens (and rolling shutter)
        # a rolling shutter may place a point seen at the frame's time outside the image (or find no row that sees it)
        with np.errstate(invalid="ignore"):
            placed = (uv[:, 0] >= 0) & (uv[:, 0] <= c.width) & (uv[:, 1] >= 0) & (uv[:, 1] <= c.height)
        seen, uv = seen[placed], uv[placed]
        self.observations.append((seen, uv))
        if "rgb" in frame.outputs:
            new = ~self.coloured[seen]
            rgb8 = (np.clip(frame.outputs["rgb"], 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)  # the PNG's pixels
            px = np.minimum(np.floor(uv[new]).astype(int), [c.width - 1, c.height - 1])
            self.colors[seen[new]] = rgb8[px[:, 1], px[:, 0]]
            self.coloured[seen[new]] = True
        self.points = frame.points  # static points never move: any frame's positions are theirs

    def close(self) -> None:
        c = self.context
        folder = Path(c.folder)
        names = [frame_names(i)[1] for i in range(len(self.observations))]
        write_colmap_model(folder / "sparse" / "0", c.K, c.width, c.height, c.poses[:len(names)], names,
                           self.observations, self.points, self.colors, text=bool(c.options.get("colmap_text")),
                           lens=c.lens)
        counts = np.bincount(np.concatenate([o[0] for o in self.observations]) if self.observations else
                             np.zeros(0, int), minlength=len(self.colors))
        keep = np.flatnonzero(counts >= 2)
        xyz = np.asarray(self.points, np.float64)[keep] if self.points is not None else np.zeros((0, 3))
        write_points_ply(folder / POINTS_PLY, xyz, self.colors[keep])


def write_points_ply(path: str | Path, xyz: np.ndarray, colors: np.ndarray) -> None:
    """``points3D.ply``: a COLMAP model's 3D points ``xyz`` (N, 3) world metres (float32 in the
    file) with their ``colors`` (N, 3) uint8."""
    write_ply(path, {"x": xyz[:, 0].astype(np.float32), "y": xyz[:, 1].astype(np.float32),
                     "z": xyz[:, 2].astype(np.float32), "red": colors[:, 0], "green": colors[:, 1], "blue": colors[:, 2]},
              comments=[f"{PLY_FORMAT_COMMENT} {FORMAT_VERSION}",
                        "the COLMAP model's 3D points (sparse/0), world metres, colour from the display PNG"])


# ---- reading ---------------------------------------------------------------------------------

# COLMAP camera model id -> number of params (every model of COLMAP 3.13 / pycolmap 4.2, ids 0-17)
_CAMERA_PARAMS = {0: 3, 1: 4, 2: 4, 3: 5, 4: 8, 5: 8, 6: 12, 7: 5, 8: 4, 9: 5, 10: 12, 11: 16, 12: 4, 13: 5, 14: 3,
                  15: 4, 16: 6, 17: 2}


class ColmapError(ValueError):
    """A COLMAP model that cannot be used (one line: which file, what is wrong, what to do)."""


@dataclass
class ColmapModel:
    """A single-camera model: ``K`` (3, 3), ``width``, ``height`` pixels, and per image (in
    name order) ``names`` and ``world_from_camera`` (T, 4, 4) OpenCV poses; ``lens`` the
    camera's distortion (generator/geometry/lens.py; PINHOLE for a pinhole camera)."""

    K: np.ndarray
    width: int
    height: int
    names: list[str]
    world_from_camera: np.ndarray
    lens: Lens = PINHOLE


def read_colmap_model(folder: str | Path) -> ColmapModel:
    """Read a COLMAP sparse model (binary, else text) with one PINHOLE, SIMPLE_PINHOLE, OPENCV,
    FULL_OPENCV (k4-k6 zero) or OPENCV_FISHEYE camera,
    refusing what would give silently wrong poses: truncated binary files (their byte counts
    are checked before pycolmap reads them), zero or non-finite intrinsics, a principal point
    outside the image, rotations that are not proper (det +1) or not finite."""
    import pycolmap

    folder = Path(folder)
    if (folder / "images.bin").is_file():
        for name in ("cameras.bin", "images.bin"):
            _check_binary_size(folder / name)
        rec, reader = pycolmap.Reconstruction(), "read_binary"
    elif (folder / "images.txt").is_file():
        rec, reader = pycolmap.Reconstruction(), "read_text"
    else:
        raise ColmapError(f"{folder}: not a COLMAP model (no images.bin or images.txt)")
    try:
        getattr(rec, reader)(str(folder))
    except Exception as exc:  # pycolmap raises whatever its C++ layer throws (RuntimeError, IndexError, ...)
        detail = str(exc).splitlines()[0][:120] if str(exc) else exc.__class__.__name__
        raise ColmapError(f"{folder}: unreadable COLMAP model ({detail}); re-export it") from None
    images = sorted(rec.images.values(), key=lambda im: im.name)
    if not images:
        raise ColmapError(f"{folder}: the COLMAP model has no images")
    cams = {im.camera_id for im in images}
    if len(cams) != 1:
        raise ColmapError(f"{folder}: {len(cams)} cameras; one camera is needed")
    cam = rec.cameras[cams.pop()]
    K, width, height, lens = _camera(cam, folder)
    poses = np.empty((len(images), 4, 4))
    for k, im in enumerate(images):
        m = np.eye(4)
        m[:3, :4] = im.cam_from_world().matrix()
        r = m[:3, :3]
        if not np.isfinite(m).all() or abs(np.linalg.det(r) - 1) > 1e-6 or np.abs(r.T @ r - np.eye(3)).max() > 1e-6:
            raise ColmapError(f"{folder}: image {im.name!r} has no proper rotation (unit quaternion); re-export the model")
        poses[k] = invert_rigid(m)  # world_from_camera, BLAS-free
    return ColmapModel(K, width, height, [im.name for im in images], poses, lens)


def _camera(cam, folder: Path) -> tuple[np.ndarray, int, int, Lens]:
    try:
        (fx, fy, cx, cy), lens = Lens.from_colmap(cam.model.name, cam.params)
    except ValueError as exc:
        raise ColmapError(f"{folder}: {exc}") from None
    width, height = int(cam.width), int(cam.height)
    if not (0 < width <= 65536 and 0 < height <= 65536):
        raise ColmapError(f"{folder}: camera size {width}x{height} pixels; the model is damaged, re-export it")
    if not all(np.isfinite([fx, fy, cx, cy])) or fx <= 0 or fy <= 0:
        raise ColmapError(f"{folder}: camera focal length fx={fx:g}, fy={fy:g} pixels; both must be positive "
                          "(a damaged or placeholder camera), re-export the model")
    if not (0 < cx < width and 0 < cy < height):
        raise ColmapError(f"{folder}: principal point ({cx:g}, {cy:g}) lies outside the {width}x{height} image; "
                          "the model is damaged, re-export it")
    return np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]), width, height, lens


def _check_binary_size(path: Path) -> None:
    """The byte count a COLMAP cameras.bin or images.bin must have, from its own counts."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ColmapError(f"{path}: unreadable ({exc.strerror})") from None
    try:
        end = (_cameras_end if path.name == "cameras.bin" else _images_end)(data)
    except (ValueError, IndexError, KeyError) as exc:
        raise ColmapError(f"{path}: damaged or truncated COLMAP file ({exc}); re-export the model") from None
    if end != len(data):
        raise ColmapError(f"{path}: damaged COLMAP file ({len(data)} bytes, its contents need {end}); re-export the model")


def _u64(data: bytes, pos: int) -> int:
    if pos + 8 > len(data):
        raise ValueError("cut short")
    return int.from_bytes(data[pos:pos + 8], "little")


def _cameras_end(data: bytes) -> int:
    n, pos = _u64(data, 0), 8
    if n > len(data) // 24:
        raise ValueError(f"it announces {n} cameras in {len(data)} bytes")
    for _ in range(n):
        if pos + 24 > len(data):
            raise ValueError("cut short")
        model = int.from_bytes(data[pos + 4:pos + 8], "little", signed=True)
        if model not in _CAMERA_PARAMS:
            raise ValueError(f"unknown camera model id {model}")
        pos += 24 + 8 * _CAMERA_PARAMS[model]
    return pos


def _images_end(data: bytes) -> int:
    n, pos = _u64(data, 0), 8
    if n > len(data) // 69:
        raise ValueError(f"it announces {n} images in {len(data)} bytes")
    for _ in range(n):
        pos += 4 + 7 * 8 + 4  # image id, quaternion, translation, camera id
        end = data.find(b"\0", pos)
        if end < 0:
            raise ValueError("cut short in an image name")
        points = _u64(data, end + 1)
        pos = end + 9 + 24 * points
        if pos > len(data):
            raise ValueError("cut short")
    return pos
