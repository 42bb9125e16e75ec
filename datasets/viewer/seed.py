"""A seed folder as a Rerun recording, read through :class:`datasets.Scene` (docs/viewer.md).

Entities (world: metres, Z up; class ids = label ids of labels.json, 65535 unlabelled):

    world/ground_truth/points     static  labelled GT cloud, subsampled (common.subsample_stride)
    world/ground_truth/mesh       static  the site's triangles at the first frame (ground_truth/mesh.ply)
    world/<kind>/path             static  the camera centres as one line strip
    world/<kind>/camera           per frame Transform3D (world_from_camera, OpenCV axes); static Pinhole
    world/<kind>/camera/<modality>   per frame, each image the seed has (images.py: rgb, depth, label,
                                  instance natively; normal, flow, ... coloured as on the contact sheet)
    world/<kind>/camera/tracks    per frame visible tracked points at their pixel positions (2D)
    world/<kind>/tracks           per frame the same points at their world positions (3D)
    coverage/<kind>               per frame coverage after the frame (share of surface points, 0..1)
    world/<kind>/lidar/<NAME>     per sweep, the returns of a --lidar sensor, coloured by class (scans.py)

Timelines: ``frame`` (t = 0 .. T-1 of each trajectory) and ``time`` (the frame's timestamp, s).
A seed is opened with :func:`open_scene`: an ordinary seed folder, or one stage
(``SEED/phase_K``) of a timeline seed (``--phases``).
"""

from __future__ import annotations

import numpy as np

from datasets.scene import DatasetError, Scene, Sequence, read_point_cloud

from .common import FRAME_TIMELINE, MAX_POINTS, TIME_TIMELINE, annotation_context, class_ids, subsample_stride
from .images import log_images
from .scans import log_scans

CLOUD_RADIUS = 0.03   # metres: GT points
TRACK_RADIUS_UI = 1.0  # UI points: tracked points, 2D and 3D (thousands per frame: small, so the image shows)
FRUSTUM_DEPTH = 4.0    # metres: where the camera's image plane is drawn in 3D
PATH_COLORS = [(255, 0, 255), (0, 220, 255), (255, 255, 255), (0, 255, 0)]  # per trajectory, not class colours


class Stage:
    """Stage K of a timeline seed (``SEED/phase_K``, ``--phases``) with what :func:`record_scene`
    reads of a :class:`Scene`: its frames through ``datasets.change.Timeline``, its GT cloud
    and mesh from ``phase_K/ground_truth``."""

    def __init__(self, timeline, stage: int):
        if not 0 <= stage < timeline.stages:
            raise DatasetError(f"{timeline.path / f'phase_{stage}'}: the timeline seed {timeline.path} has stages "
                               f"0 to {timeline.stages - 1}; view one of those")
        self.timeline, self.stage = timeline, stage
        self.path = timeline.path / f"phase_{stage}"
        self.seed, self.labels, self.trajectories = timeline.seed, timeline.labels, timeline.trajectories

    def __getitem__(self, kind: str) -> Sequence:
        return self.timeline.sequence(self.stage, kind)

    def point_cloud(self, static_only: bool = False) -> dict:
        """The stage's labelled ground-truth cloud (``phase_K/ground_truth/points.ply``), read as
        :meth:`Scene.point_cloud` reads a seed's."""
        return read_point_cloud(self.path, static_only)


def open_scene(path) -> Scene | Stage:
    """What ``python -m datasets.view PATH`` shows: an ordinary seed folder as a :class:`Scene`,
    ``SEED/phase_K`` of a timeline seed as its :class:`Stage` K; a timeline seed's own folder
    is refused with the command that views a stage."""
    from pathlib import Path

    from datasets.change import Timeline
    from exporters.manifest import read_manifest, stage_count, timeline_stage

    path = Path(path)
    stage = timeline_stage(path) if path.is_dir() else None
    if stage is not None:
        return Stage(Timeline(stage[0]), stage[1])
    manifest = read_manifest(path) if path.is_dir() else None
    if manifest is not None and stage_count(manifest) > 1:
        n = stage_count(manifest)
        raise DatasetError(f"{path}: a timeline seed of {n} stages (--phases); view one stage at a time: "
                           f"python -m datasets.view {path / 'phase_K'} (K = 0 to {n - 1})")
    return Scene(path)


def recording_id(scene: Scene | Stage) -> str:
    """seed_NNNNNN, or seed_NNNNNN_phase_K for a stage."""
    return f"seed_{scene.seed:06d}" + (f"_phase_{scene.stage}" if isinstance(scene, Stage) else "")


def default_file_name(scene: Scene | Stage) -> str:
    """<seed folder name>.rrd, or <seed folder name>_phase_K.rrd for a stage."""
    if isinstance(scene, Stage):
        return f"{scene.timeline.path.resolve().name}_phase_{scene.stage}.rrd"
    return f"{scene.path.resolve().name}.rrd"


def record_scene(rec, scene: Scene, kinds: list[str] | None = None, max_points: int = MAX_POINTS,
                 progress=None) -> dict:
    """Log everything of ``scene`` (trajectories ``kinds``, default all) on ``rec``; returns
    counts (``points``: GT points logged, ``frames`` and ``sweeps``: per trajectory)."""
    import rerun as rr

    kinds = scene.trajectories if kinds is None else kinds
    rec.log("/", annotation_context(scene.labels), static=True)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    counts = {"points": log_cloud(rec, scene, max_points), "frames": {}, "sweeps": {}}
    log_mesh(rec, scene)
    for i, kind in enumerate(kinds):
        counts["frames"][kind] = log_sequence(rec, scene[kind], progress, PATH_COLORS[i % len(PATH_COLORS)])
        counts["sweeps"][kind] = log_scans(rec, scene[kind])
    return counts


def blueprint(scene, kinds: list[str]):
    """The default layout: the site in 3D (the cameras show their RGB only: every other image
    is excluded from it, so none is drawn on the frustum's image plane); per trajectory its RGB
    with the tracks, labels and depth (those it has); the coverage curves; the time panel on
    the frame timeline, played at the first trajectory's frame rate."""
    import rerun.blueprint as rrb

    def camera_view(kind: str, name: str, contents: list[str]):
        return rrb.Spatial2DView(name=f"{kind}: {name}", origin=f"world/{kind}/camera",
                                 contents=[f"$origin/{c}" for c in contents])

    rows, hidden = [], []
    for kind in kinds:
        modalities = scene[kind].modalities
        views = [camera_view(kind, "RGB + tracks" if "rgb" in modalities else "tracks",
                             ["rgb", "tracks"] if "rgb" in modalities else ["tracks"])]
        views += [camera_view(kind, title, [name]) for name, title in (("label", "labels"), ("depth", "depth"))
                  if name in modalities]
        rows.append(rrb.Horizontal(*views))
        hidden += [f"- $origin/{kind}/camera/{name}" for name in modalities if name != "rgb"]
    site = rrb.Spatial3DView(name="site", origin="world", contents=["$origin/**"] + hidden)
    fps = frame_rate(scene[kinds[0]])
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

    from exporters.ground_truth import GroundTruthError, read_mesh

    try:
        mesh = read_mesh(scene.path / "ground_truth")
    except GroundTruthError as exc:
        raise DatasetError(str(exc)) from None
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
    if "instance" in seq.modalities:  # object ids: not label names
        rec.log(f"{base}/camera/instance", rr.AnnotationContext([]), static=True)
    coverage, labels = seq.coverage, seq.points["label"]
    frames = range(len(seq))
    for t in (progress(frames, seq.kind) if progress else frames):
        frame = seq[t]
        rec.set_time(FRAME_TIMELINE, sequence=t)
        rec.set_time(TIME_TIMELINE, duration=frame.timestamp)
        rec.log(f"{base}/camera", rr.Transform3D(translation=frame.pose[:3, 3], mat3x3=frame.pose[:3, :3]))
        log_images(rec, f"{base}/camera", frame, seq.labels)
        vis = seq.visible_tracks(t)
        ids = class_ids(labels[vis["ids"]])
        rec.log(f"{base}/camera/tracks", rr.Points2D(vis["xy"], class_ids=ids,
                                                     radii=rr.Radius.ui_points(TRACK_RADIUS_UI)))
        rec.log(f"{base}/tracks", rr.Points3D(seq.point_positions(t, vis["ids"]), class_ids=ids,
                                              radii=rr.Radius.ui_points(TRACK_RADIUS_UI)))
        if t < len(coverage):
            rec.log(f"coverage/{seq.kind}", rr.Scalars(float(coverage[t])))
    return len(seq)
