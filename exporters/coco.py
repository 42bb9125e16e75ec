"""Instance masks and 2D boxes of a trajectory in COCO format (``<kind>/coco.json``).

Written by the ``coco`` sink from the frames' ``instance`` maps (pixel-centre object ids) and
read back by :class:`CocoReader`; pycocotools opens the file as it is. Schema (docs/format.md):

- ``categories``: the label table, ``id`` = label id + 1 (COCO keeps 0 for "no object"),
  ``name`` the class, ``label_id`` our label id.
- ``images``: one per frame, ``id`` = frame index + 1, ``file_name`` the frame's PNG,
  ``width``, ``height``, ``frame`` (0-based index) and ``timestamp`` (seconds).
- ``annotations``: one per instance with at least one pixel in the frame: ``segmentation``
  (compressed RLE, ``size`` [H, W]), ``area`` (pixels), ``bbox`` [x, y, w, h] the tight box of
  those pixels (pixel edges: the top-left image corner is (0, 0)), ``iscrowd`` 0,
  ``category_id``, ``instance_id`` (the ``instance`` map's id, index into the object table),
  ``object`` (its name) and ``amodal_bbox`` [x, y, w, h]: the box of the whole object's
  triangles projected into the image, clipped to the part beyond the camera's clip start
  and inside the image, ignoring occlusion (``generator.geometry.boxes.amodal_box``; float pixels;
  not written for a camera with a distorting lens, ``--camera-model``: the box's exact
  construction needs straight edges).
- ``info``: ``format_version``, ``conventions``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pycocotools.mask as mask_utils

from generator.geometry.boxes import amodal_box, part_world_matrices, tight_boxes, used_vertices
from generator.geometry.camera import rows_times

from . import FORMAT_VERSION
from .frames import frame_names
from .hdf5 import DamagedFileError, REMEDY
from .jsonfile import check_format_version, read_json_file
from .sinks import FrameRecord, TrajectoryContext, register_sink

FILE_NAME = "coco.json"
CONVENTIONS = ("pixels; bbox and amodal_bbox [x, y, w, h] with the image's top-left corner at (0, 0) (the top-left "
               "pixel's centre is (0.5, 0.5)); masks from the instance id at each pixel centre; category_id = label id + 1; "
               "image id = frame index + 1")


def category_id(label_id: int) -> int:
    """COCO category id of one of our label ids (COCO reserves 0)."""
    return int(label_id) + 1


def encode_masks(instance: np.ndarray, ids: np.ndarray) -> list[dict]:
    """Compressed RLE (pycocotools' own bytes, counts as str) of ``instance == id`` for every
    id, from one pass over the map's runs in column-major order (COCO's pixel order)."""
    h, w = instance.shape
    if len(ids) == 0:
        return []
    seq = np.ascontiguousarray(instance.T).ravel()
    change = np.flatnonzero(seq[1:] != seq[:-1]) + 1
    starts, ends = np.concatenate([[0], change]), np.concatenate([change, [seq.size]])
    order = np.argsort(seq[starts], kind="stable")  # runs grouped by id, in pixel order within an id
    grouped = seq[starts][order]
    rles = []
    for iid in np.asarray(ids).tolist():
        a, b = np.searchsorted(grouped, [iid, iid + 1])
        s0, e0 = starts[order[a:b]], ends[order[a:b]]
        if len(s0) == 0:  # not in the map: an empty mask
            rles.append({"size": [h, w], "counts": [int(seq.size)]})
            continue
        counts = np.empty(2 * len(s0) + 1, np.int64)
        counts[0:-1:2] = s0 - np.concatenate([[0], e0[:-1]])  # background run before each run of the id
        counts[1::2] = e0 - s0
        counts[-1] = seq.size - e0[-1]
        rles.append({"size": [h, w], "counts": (counts if counts[-1] else counts[:-1]).tolist()})
    compressed = mask_utils.frPyObjects(rles, h, w)
    return [{"size": [h, w], "counts": r["counts"].decode("ascii")} for r in compressed]


def _xywh(box) -> list[float]:
    x0, y0, x1, y1 = box
    return [x0, y0, x1 - x0, y1 - y0]


@register_sink("coco")
class CocoWriter:
    """Collects one trajectory's annotations frame by frame; :meth:`close` writes coco.json."""

    def __init__(self, context: TrajectoryContext):
        self.context = context
        self.path = Path(context.folder) / FILE_NAME
        self.images: list[dict] = []
        self.annotations: list[dict] = []
        self.used: dict[int, np.ndarray] = {}  # instance id -> used_vertices, computed on first sight
        self.near = float(getattr(context, "clip", (0.0, None))[0])  # the camera's clip start, metres

    def add_frame(self, frame: FrameRecord) -> None:
        ctx = self.context
        if "instance" not in frame.outputs:  # --outputs without instance: nothing to annotate
            return
        instance = np.asarray(frame.outputs["instance"])
        self.images.append({"id": frame.index + 1, "file_name": frame_names(frame.index)[1], "width": ctx.width,
                            "height": ctx.height, "frame": frame.index, "timestamp": float(frame.timestamp)})
        ids = np.unique(instance)
        ids = ids[ids >= 0]
        matrices = part_world_matrices(ctx.parts, ctx.dynamic_objects, frame.object_matrices)
        tight, counts = tight_boxes(instance, ids)
        for k, (iid, rle) in enumerate(zip(ids.tolist(), encode_masks(instance, ids))):
            part, row = ctx.parts[iid], ctx.instances[iid]
            m = matrices[iid]
            if iid not in self.used:
                self.used[iid] = used_vertices(part.faces)
            annotation = {
                "id": len(self.annotations) + 1, "image_id": frame.index + 1, "category_id": category_id(row["label_id"]),
                "segmentation": rle, "area": int(counts[k]), "bbox": _xywh(tight[k].tolist()), "iscrowd": 0,
                "instance_id": int(iid), "object": row["object"]}
            if ctx.lens.ideal and ctx.rolling is None:  # the exact box assumes straight edges and one pose
                amodal = amodal_box(rows_times(part.vertices, m[:3, :3].T) + m[:3, 3], part.faces,
                                    frame.world_from_camera, ctx.K, ctx.width, ctx.height, self.used[iid], near=self.near)
                annotation["amodal_bbox"] = _xywh(amodal if amodal is not None else tight[k].tolist())
            self.annotations.append(annotation)

    def close(self) -> Path | None:
        ctx = self.context
        if "instance" not in ctx.modalities:
            return None
        doc = {"info": {"description": f"buildee-sites seed {ctx.seed}, trajectory {ctx.kind}",
                        "format_version": FORMAT_VERSION, "conventions": CONVENTIONS},
               "licenses": [],
               "categories": [{"id": category_id(i), "name": name, "supercategory": "construction_site", "label_id": i}
                              for i, name in enumerate(ctx.labels)],
               "images": self.images, "annotations": self.annotations}
        self.path.write_text(json.dumps(doc, separators=(",", ":")))
        return self.path


class CocoReader:
    """A trajectory's coco.json: :meth:`frame` gives one frame's annotations as arrays.
    A file of another format version or structure raises :class:`DamagedFileError`."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        doc = read_json_file(self.path, "COCO file")
        try:
            check_format_version(self.path, doc["info"]["format_version"])
            self.categories = {c["id"]: c for c in doc["categories"]}
            self.images = {int(im["frame"]): im for im in doc["images"]}
            by_image: dict[int, list] = {im["id"]: [] for im in doc["images"]}
            for a in doc["annotations"]:
                by_image[a["image_id"]].append(a)
            self._by_frame = {f: by_image[im["id"]] for f, im in self.images.items()}
        except (KeyError, TypeError) as exc:
            raise DamagedFileError(f"{self.path}: not a coco.json of this format ({exc.__class__.__name__}: {exc}); "
                                   f"{REMEDY}") from None

    def __len__(self) -> int:
        return len(self.images)

    def annotations(self, frame: int) -> list[dict]:
        """The raw COCO annotations of frame ``frame`` (0-based)."""
        if frame not in self._by_frame:
            raise DamagedFileError(f"{self.path}: has no image for frame {frame}; {REMEDY}")
        return self._by_frame[frame]

    def frame(self, frame: int) -> dict:
        """Frame ``frame``'s instances as arrays (n = instances with pixels): ``instance_id``,
        ``label`` (our label id), ``category_id``, ``area`` (n,) ints; ``bbox`` and
        ``amodal_bbox`` (n, 4) float64 as (x0, y0, x1, y1) pixel edges (NaN where the file has none:
        a distorting lens); ``masks`` is not
        included: instance k's mask is ``frame.instance == instance_id[k]`` (the RLE decodes
        to exactly that; :meth:`masks` decodes them)."""
        anns = self.annotations(frame)

        def xyxy(key):
            b = np.array([a[key] if key == "bbox" or key in a else [np.nan] * 4 for a in anns], np.float64).reshape(-1, 4)
            return np.column_stack([b[:, :2], b[:, :2] + b[:, 2:]])

        try:
            return {"instance_id": np.array([a["instance_id"] for a in anns], np.int32),
                    "category_id": np.array([a["category_id"] for a in anns], np.int32),
                    "label": np.array([self.categories[a["category_id"]]["label_id"] for a in anns], np.int32),
                    "area": np.array([a["area"] for a in anns], np.int64),
                    "bbox": xyxy("bbox"), "amodal_bbox": xyxy("amodal_bbox")}
        except (KeyError, TypeError, ValueError) as exc:
            raise DamagedFileError(f"{self.path}: frame {frame}'s annotations are not of this format "
                                   f"({exc.__class__.__name__}: {exc}); {REMEDY}") from None

    def masks(self, frame: int) -> np.ndarray:
        """(n, H, W) bool decoded masks of frame ``frame``, in :meth:`frame`'s order."""
        anns = self.annotations(frame)
        im = self.images[frame]
        if not anns:
            return np.zeros((0, im["height"], im["width"]), bool)
        rles = [{"size": a["segmentation"]["size"], "counts": a["segmentation"]["counts"].encode("ascii")} for a in anns]
        return np.moveaxis(mask_utils.decode(rles), -1, 0).astype(bool)
