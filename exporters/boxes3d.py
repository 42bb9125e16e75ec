"""Oriented 3D boxes of the object instances in view, per frame (``<kind>/boxes3d.json``).

Written by the ``boxes3d`` sink, read back by :class:`Boxes3DReader`. Every instance (a rigid
part: the ``instance`` map's ids) gets one box for the whole trajectory in its own frame
(``generator.geometry.boxes.upright_box``): for static parts, which are stored in world
coordinates, the upright box (world Z) with the smallest footprint; for moving parts the
same construction in the object's frame, carried to the world by its world_from_object
matrix at each frame (so a truck's box turns with the truck). Schema (docs/format.md):

- ``labels``: the label table; ``instances``: ``{"id", "object", "label_id", "dynamic"}`` rows.
- ``frames``: one per frame, ``{"frame", "timestamp", "boxes": [...]}``; a box per instance
  with at least one pixel in the frame's ``instance`` map: ``instance``, ``label_id``,
  ``centre`` [3] metres (world), ``size`` [3] metres (full edge lengths along the box axes),
  ``rotation`` [3][3] (rows of world_from_box: its columns are the box's x, y, z axes in
  the world), ``pixels`` (pixels whose centre sees the instance) and ``pixel_share``
  (``pixels`` / (width x height): the share of the image the instance covers).
- ``format_version``, ``conventions``, ``units``, ``width``, ``height``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from generator.geometry.boxes import Box3D, moved_box, part_world_matrices, upright_box

from . import FORMAT_VERSION
from .hdf5 import REMEDY, DamagedFileError
from .jsonfile import check_format_version, read_json_file
from .sinks import FrameRecord, TrajectoryContext, register_sink

FILE_NAME = "boxes3d.json"
UNITS = {"centre": "metres, world frame (Z up)", "size": "metres, full edge lengths along the box axes",
         "rotation": "world_from_box rotation, rows of a 3x3 matrix (columns = box axes in the world)",
         "pixels": "count of pixels whose centre sees the instance",
         "pixel_share": "pixels / (width * height), 0..1", "timestamp": "seconds"}
CONVENTIONS = ("a point p is inside when |R^T (p - centre)| <= size / 2 per axis; static parts: upright box (z axis = "
               "world Z) with the minimum footprint area; moving parts: that box in the object frame, moved by its "
               "world_from_object matrix; a box per instance with at least one pixel in the frame")


def local_boxes(parts: list) -> list[Box3D]:
    """Each part's box in its own frame (world for static parts, object frame for moving ones)."""
    return [upright_box(p.vertices) for p in parts]


@register_sink("boxes3d")
class Boxes3DWriter:
    """Collects the boxes of the instances in view frame by frame; :meth:`close` writes the file."""

    def __init__(self, context: TrajectoryContext):
        self.context = context
        self.path = Path(context.folder) / FILE_NAME
        self.local = local_boxes(context.parts)
        self.frames: list[dict] = []

    def add_frame(self, frame: FrameRecord) -> None:
        ctx = self.context
        if "instance" not in frame.outputs:  # --outputs without instance: nothing to annotate
            return
        instance = np.asarray(frame.outputs["instance"])
        counts = np.bincount(instance[instance >= 0].ravel(), minlength=len(ctx.parts))
        matrices = part_world_matrices(ctx.parts, ctx.dynamic_objects, frame.object_matrices)
        boxes = []
        for iid in np.flatnonzero(counts).tolist():
            part = ctx.parts[iid]
            box = moved_box(self.local[iid], part.vertices, matrices[iid]) if part.dynamic else self.local[iid]
            boxes.append({"instance": iid, "label_id": int(ctx.instances[iid]["label_id"]),
                          "centre": box.centre.tolist(), "size": box.size.tolist(), "rotation": box.rotation.tolist(),
                          "pixels": int(counts[iid]), "pixel_share": float(counts[iid]) / (ctx.width * ctx.height)})
        self.frames.append({"frame": frame.index, "timestamp": float(frame.timestamp), "boxes": boxes})

    def close(self) -> Path | None:
        ctx = self.context
        if "instance" not in ctx.modalities:
            return None
        doc = {"format_version": FORMAT_VERSION, "conventions": CONVENTIONS, "units": UNITS,
               "width": ctx.width, "height": ctx.height, "labels": list(ctx.labels),
               "instances": [{"id": i, "object": row["object"], "label_id": int(row["label_id"]),
                              "dynamic": bool(ctx.parts[i].dynamic)} for i, row in enumerate(ctx.instances)],
               "frames": self.frames}
        self.path.write_text(json.dumps(doc, separators=(",", ":")))
        return self.path


class Boxes3DReader:
    """A trajectory's boxes3d.json; :meth:`frame` gives one frame's boxes as arrays. A file of
    another format version or structure raises :class:`DamagedFileError`."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        doc = read_json_file(self.path, "boxes file")
        check_format_version(self.path, doc.get("format_version") if isinstance(doc, dict) else None)
        try:
            self.labels, self.instances, self.units = list(doc["labels"]), list(doc["instances"]), dict(doc["units"])
            self.width, self.height = int(doc["width"]), int(doc["height"])
            self._frames = {int(f["frame"]): f["boxes"] for f in doc["frames"]}
            self.timestamps = np.array([f["timestamp"] for f in doc["frames"]], np.float64)
        except (KeyError, TypeError, ValueError) as exc:
            raise DamagedFileError(f"{self.path}: not a boxes3d.json of this format ({exc.__class__.__name__}); "
                                   f"{REMEDY}") from None

    def __len__(self) -> int:
        return len(self._frames)

    def frame(self, frame: int) -> dict:
        """Frame ``frame``'s boxes (n = instances in view): ``instance``, ``label``, ``pixels``
        (n,) ints, ``pixel_share`` (n,), ``centre``, ``size`` (n, 3) metres, ``rotation``
        (n, 3, 3) world_from_box."""
        if frame not in self._frames:
            raise DamagedFileError(f"{self.path}: has no frame {frame}; {REMEDY}")
        boxes = self._frames[frame]
        try:
            out = {"instance": np.array([b["instance"] for b in boxes], np.int32),
                   "label": np.array([b["label_id"] for b in boxes], np.int32),
                   "centre": np.array([b["centre"] for b in boxes], np.float64).reshape(-1, 3),
                   "size": np.array([b["size"] for b in boxes], np.float64).reshape(-1, 3),
                   "rotation": np.array([b["rotation"] for b in boxes], np.float64).reshape(-1, 3, 3),
                   "pixels": np.array([b["pixels"] for b in boxes], np.int64),
                   "pixel_share": np.array([b["pixel_share"] for b in boxes], np.float64)}
        except (KeyError, TypeError, ValueError) as exc:
            raise DamagedFileError(f"{self.path}: damaged box in frame {frame} ({exc.__class__.__name__}); {REMEDY}") from None
        return out

    def boxes(self, frame: int) -> list[Box3D]:
        """Frame ``frame``'s boxes as :class:`generator.geometry.boxes.Box3D` (same order as :meth:`frame`)."""
        d = self.frame(frame)
        return [Box3D(c, s, r) for c, s, r in zip(d["centre"], d["size"], d["rotation"])]
