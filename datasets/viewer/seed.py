"""A seed folder as a Rerun recording, read through :class:`datasets.Scene` (docs/viewer.md).

Entities (world: metres, Z up; class ids = label ids of labels.json, 65535 unlabelled):

    world/ground_truth/points     static  labelled GT cloud, subsampled (common.subsample_stride)
    world/ground_truth/mesh       static  the site's triangles at the first frame (ground_truth/mesh.ply)
    world/<kind>/path             static  the camera centres as one line strip
    world/<kind>/camera           per frame Transform3D (world_from_camera, OpenCV axes); static Pinhole
    world/<kind>/camera/rgb|depth|label|instance   per frame images (and any other per-pixel array a frame holds)
    world/<kind>/camera/tracks    per frame visible tracked points at their pixel positions (2D)
    world/<kind>/tracks           per frame the same points at their world positions (3D)
    coverage/<kind>               per frame coverage after the frame (share of surface points, 0..1)

Timelines: ``frame`` (t = 0 .. T-1 of each trajectory) and ``time`` (the frame's timestamp, s).
"""

from __future__ import annotations

import numpy as np

from datasets.scene import DatasetError, Frame, Scene, Sequence

from .common import FRAME_TIMELINE, MAX_POINTS, TIME_TIMELINE, annotation_context, class_ids, subsample_stride

STANDARD_IMAGES = ("rgb", "depth", "label", "instance")
CLOUD_RADIUS = 0.03   # metres: GT points
TRACK_RADIUS_UI = 1.0  # UI points: tracked points, 2D and 3D (thousands per frame: small, so the image shows)
FRUSTUM_DEPTH = 4.0    # metres: where the camera's image plane is drawn in 3D
PATH_COLORS = [(255, 0, 255), (0, 220, 255), (255, 255, 255), (0, 255, 0)]  # per trajectory, not class colours


def record_scene(rec, scene: Scene, kinds: list[str] | None = None, max_points: int = MAX_POINTS,
                 progress=None) -> dict:
    """Log everything of ``scene`` (trajectories ``kinds``, default all) on ``rec``; returns
    counts (``points``: GT points logged, ``frames``: per trajectory)."""
    import rerun as rr

    kinds = scene.trajectories if kinds is None else kinds
    rec.log("/", annotation_context(scene.labels), static=True)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    counts = {"points": log_cloud(rec, scene, max_points), "frames": {}}
    log_mesh(rec, scene)
    for i, kind in enumerate(kinds):
        counts["frames"][kind] = log_sequence(rec, scene[kind], progress, PATH_COLORS[i % len(PATH_COLORS)])
    return counts


def blueprint(kinds: list[str], fps: float | None = None):
    """The default layout: the site in 3D (the cameras show their RGB; depth, labels and
    instances only in 2D); per trajectory its RGB with the tracks, labels and depth; the
    coverage curves; the time panel on the frame timeline, played at ``fps`` (frames per second)."""
    import rerun.blueprint as rrb

    def camera_view(kind: str, name: str, contents: list[str]):
        return rrb.Spatial2DView(name=f"{kind}: {name}", origin=f"world/{kind}/camera",
                                 contents=[f"$origin/{c}" for c in contents])

    rows = [rrb.Horizontal(camera_view(kind, "RGB + tracks", ["rgb", "tracks"]), camera_view(kind, "labels", ["label"]),
                           camera_view(kind, "depth", ["depth"])) for kind in kinds]
    site = rrb.Spatial3DView(name="site", origin="world", contents=["$origin/**"] + [
        f"- $origin/{kind}/camera/{image}" for kind in kinds for image in ("depth", "label", "instance")])
    return rrb.Blueprint(rrb.Horizontal(site, rrb.Vertical(*rows, rrb.TimeSeriesView(name="coverage", origin="coverage")),
                                        column_shares=[3, 2]),
                         rrb.SelectionPanel(state="collapsed"), rrb.BlueprintPanel(state="collapsed"),
                         rrb.TimePanel(timeline=FRAME_TIMELINE, fps=fps, state="collapsed"))


def frame_rate(seq: Sequence) -> float | None:
    """Frames per second of a trajectory, from its timestamps (None with fewer than 2 frames)."""
    steps = np.diff(seq.timestamps)
    return float(1.0 / np.median(steps)) if len(steps) and np.median(steps) > 0 else None


def log_cloud(rec, scene: Scene, max_points: int) -> int:
    import rerun as rr

    cloud = scene.point_cloud()
    k = subsample_stride(len(cloud["xyz"]), max_points)
    xyz, labels = cloud["xyz"][::k], cloud["label"][::k]
    rec.log("world/ground_truth/points", rr.Points3D(xyz, class_ids=class_ids(labels), radii=CLOUD_RADIUS),
            static=True)
    return len(xyz)


def log_mesh(rec, scene: Scene) -> None:
    import rerun as rr

    from exporters.ply import PlyError, read_ply

    path = scene.path / "ground_truth" / "mesh.ply"
    try:
        mesh = read_ply(path)
    except PlyError as exc:
        raise DatasetError(f"{exc}; regenerate this seed with python -m generator") from None
    if mesh.faces is None:
        raise DatasetError(f"{path}: no faces; not the ground-truth mesh of python -m generator, regenerate this seed")
    colors = np.stack([mesh.vertex[c] for c in ("red", "green", "blue")], 1) if "red" in mesh.vertex else None
    rec.log("world/ground_truth/mesh", rr.Mesh3D(vertex_positions=mesh.points.astype(np.float32),
                                                 triangle_indices=mesh.faces.astype(np.uint32),
                                                 vertex_colors=colors), static=True)


def log_sequence(rec, seq: Sequence, progress=None, color=PATH_COLORS[0]) -> int:
    """One trajectory: camera path, pinhole, and per frame pose, images, tracks, coverage."""
    import rerun as rr

    base = f"world/{seq.kind}"
    rec.log(f"{base}/path", rr.LineStrips3D([seq.poses[:, :3, 3]], radii=rr.Radius.ui_points(2.0), colors=[color]),
            static=True)
    rec.log(f"{base}/camera", rr.Pinhole(image_from_camera=seq.K, resolution=[seq.width, seq.height],
                                         camera_xyz=rr.ViewCoordinates.RDF, image_plane_distance=FRUSTUM_DEPTH,
                                         color=color, line_width=rr.Radius.ui_points(2.0)), static=True)
    rec.log(f"{base}/camera/instance", rr.AnnotationContext([]), static=True)  # object ids: not label names
    coverage, labels = seq.coverage, seq.points["label"]
    frames = range(len(seq))
    for t in (progress(frames, seq.kind) if progress else frames):
        frame = seq[t]
        rec.set_time(FRAME_TIMELINE, sequence=t)
        rec.set_time(TIME_TIMELINE, duration=frame.timestamp)
        rec.log(f"{base}/camera", rr.Transform3D(translation=frame.pose[:3, 3], mat3x3=frame.pose[:3, :3]))
        log_images(rec, f"{base}/camera", frame)
        vis = seq.visible_tracks(t)
        ids = class_ids(labels[vis["ids"]])
        rec.log(f"{base}/camera/tracks", rr.Points2D(vis["xy"], class_ids=ids,
                                                     radii=rr.Radius.ui_points(TRACK_RADIUS_UI)))
        rec.log(f"{base}/tracks", rr.Points3D(seq.point_positions(t, vis["ids"]), class_ids=ids,
                                              radii=rr.Radius.ui_points(TRACK_RADIUS_UI)))
        if t < len(coverage):
            rec.log(f"coverage/{seq.kind}", rr.Scalars(float(coverage[t])))
    return len(seq)


def log_images(rec, path: str, frame: Frame) -> None:
    """RGB as 8-bit sRGB (rounded, as the frames' PNGs), depth in metres (0 where none),
    labels and instances as segmentation images, any other per-pixel array scaled to its range."""
    import rerun as rr

    rgb = np.round(np.clip(frame.rgb.astype(np.float32), 0, 1) * 255).astype(np.uint8)
    rec.log(f"{path}/rgb", rr.Image(rgb))
    depth = np.where(np.isfinite(frame.depth), frame.depth, 0).astype(np.float32)
    rec.log(f"{path}/depth", rr.DepthImage(depth, meter=1.0))
    rec.log(f"{path}/label", rr.SegmentationImage(class_ids(frame.label)))
    rec.log(f"{path}/instance", rr.SegmentationImage(class_ids(frame.instance)))
    for name, value in frame.as_dict().items():
        if name not in STANDARD_IMAGES and isinstance(value, np.ndarray) and value.shape[:2] == frame.depth.shape:
            rec.log(f"{path}/{name}", rr.Image(scaled_to_range(value)))


def scaled_to_range(a: np.ndarray) -> np.ndarray:
    """An array of any type as 8-bit, its finite min..max mapped to 0..255 (non-finite: 0)."""
    a = a.astype(np.float64)
    ok = np.isfinite(a)
    if not ok.any():
        return np.zeros(a.shape, np.uint8)
    lo, hi = a[ok].min(), a[ok].max()
    out = np.where(ok, (a - lo) / (hi - lo if hi > lo else 1.0), 0)
    return np.round(out * 255).astype(np.uint8)
