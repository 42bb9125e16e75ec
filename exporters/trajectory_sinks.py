"""The per-frame exports of a trajectory other than the frame files (frames.py) and the
nerfstudio files (nerfstudio.py), each a sink (exporters/sinks.py): point tracks, the COLMAP
model and its coloured points, coverage, the contact sheet and the site map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from generator.geometry.camera import project

from . import FORMAT_VERSION
from .frames import frame_names
from .sinks import FrameRecord, TrajectoryContext, register_sink

PLY_FORMAT_COMMENT = "buildee format"  # points3D.ply's header comment, followed by the format version

PREVIEW_FRAMES = 6  # rows of each trajectory's contact sheet
UNCOLOURED = (128, 128, 128)  # COLMAP point colour when no rgb is written


@register_sink("tracks")
class TracksSink:
    """``tracks.h5``: every frame's visible points, poses and object matrices (exporters/tracks.py)."""

    def __init__(self, context: TrajectoryContext):
        from .tracks import TrackWriter

        c = context
        self.writer = TrackWriter(Path(c.folder) / "tracks.h5", c.point_table, c.dynamic_objects, c.labels, c.K,
                                  c.width, c.height, seed=c.seed)

    def add_frame(self, frame: FrameRecord) -> None:
        self.writer.add_frame(frame.timestamp, frame.world_from_camera, frame.points, frame.visible,
                              frame.object_matrices, frame.coverage)

    def close(self) -> None:
        self.writer.close()


@register_sink("colmap")
class ColmapSink:
    """``sparse/0`` (COLMAP model: exact poses, keypoints at the projections of the visible
    static points, 3D points seen in at least two frames, coloured from the display PNG where
    first seen) and ``points3D.ply`` (those 3D points with their colours, for splatting
    trainers: transforms.json's ``ply_file_path``)."""

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
        uv, _ = project(frame.points[seen], frame.world_from_camera, c.K)
        self.observations.append((seen, uv))
        if "rgb" in frame.outputs:
            new = ~self.coloured[seen]
            rgb8 = (np.clip(frame.outputs["rgb"], 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)  # the PNG's pixels
            px = np.minimum(np.floor(uv[new]).astype(int), [c.width - 1, c.height - 1])
            self.colors[seen[new]] = rgb8[px[:, 1], px[:, 0]]
            self.coloured[seen[new]] = True
        self.points = frame.points  # static points never move: any frame's positions are theirs

    def close(self) -> None:
        from .colmap import write_colmap_model
        from .nerfstudio import POINTS_PLY
        from .ply import write_ply

        c = self.context
        folder = Path(c.folder)
        names = [frame_names(i)[1] for i in range(len(self.observations))]
        write_colmap_model(folder / "sparse" / "0", c.K, c.width, c.height, c.poses[:len(names)], names,
                           self.observations, self.points, self.colors, text=bool(c.options.get("colmap_text")))
        counts = np.bincount(np.concatenate([o[0] for o in self.observations]) if self.observations else
                             np.zeros(0, int), minlength=len(self.colors))
        keep = np.flatnonzero(counts >= 2)
        xyz = np.asarray(self.points, np.float64)[keep] if self.points is not None else np.zeros((0, 3))
        write_ply(folder / POINTS_PLY, {"x": xyz[:, 0].astype(np.float32), "y": xyz[:, 1].astype(np.float32),
                                        "z": xyz[:, 2].astype(np.float32), "red": self.colors[keep, 0],
                                        "green": self.colors[keep, 1], "blue": self.colors[keep, 2]},
                  comments=[f"{PLY_FORMAT_COMMENT} {FORMAT_VERSION}",
                            "the COLMAP model's 3D points (sparse/0), world metres, colour from the display PNG"])


@register_sink("coverage")
class CoverageSink:
    """``coverage.json``: share of surface points observed at least once after each frame, and its AUC."""

    def __init__(self, context: TrajectoryContext):
        self.path = Path(context.folder) / "coverage.json"
        self.coverage: list[float] = []

    def add_frame(self, frame: FrameRecord) -> None:
        self.coverage.append(float(frame.coverage))

    def close(self) -> None:
        cov = self.coverage
        auc = float(np.trapezoid(cov, np.linspace(0, 1, len(cov))))  # one frame: 0, as the paper's np.trapz
        self.path.write_text(json.dumps({
            "coverage": cov, "units": "share of surface points observed at least once, after each frame (0..1)",
            "auc": auc}))


@register_sink("previews")
class PreviewSink:
    """``contact_sheet.png``: up to 6 frames spread over the trajectory, one column per
    written modality that has a preview colouring (exporters/previews.py)."""

    def __init__(self, context: TrajectoryContext):
        from .modalities import MODALITIES

        self.context = context
        T = len(context.poses)
        self.rows = set(np.linspace(0, T - 1, min(PREVIEW_FRAMES, T)).round().astype(int).tolist())
        self.names = [n for n in context.modalities if MODALITIES[n].preview is not None]
        self.frames: list[dict] = []

    def add_frame(self, frame: FrameRecord) -> None:
        if frame.index in self.rows and self.names:
            self.frames.append({"index": frame.index} | {n: frame.outputs[n] for n in self.names})

    def close(self) -> None:
        from .previews import contact_sheet

        if self.frames:
            contact_sheet(Path(self.context.folder) / "contact_sheet.png", self.frames, self.context.labels, self.names)


@register_sink("map")
class MapSink:
    """``map.png``: the trajectory over the top-down site map (when ``options["plan"]`` holds
    the generated site's plan)."""

    def __init__(self, context: TrajectoryContext):
        self.context = context

    def add_frame(self, frame: FrameRecord) -> None:
        pass

    def close(self) -> None:
        plan = self.context.options.get("plan")
        if plan is not None:
            from generator.scene.site_map import draw_map

            draw_map(plan, Path(self.context.folder) / "map.png", trajectory=np.asarray(self.context.poses)[:, :3, 3])
