"""What ``Simulator.render()`` and ``Simulator.render_geometry()`` do: a Blender render for
colour and the other ``render`` modalities asked for, each from the Blender passes its entry
declares (exporters/modalities.py), with depth, labels and instance ids from the Simulator's
``ground_truth`` source (docs/rendering.md "Ground truth"). The Simulator owns one
:class:`ViewRenderer` and hands it the view (pose, camera, frame) at each call.
"""

from __future__ import annotations

import time

import numpy as np

from exporters.modalities import CRYPTO_OBJECT, DEPTH, MODALITIES, OBJECT_INDEX, blender_passes, resolve

from .blender.extract import PassTable, label_of, objects_by_name
from .blender.render import Renderer
from .geometry.pixel_truth import CameraModel, PixelTruth, check_ground_truth
from .geometry.raycam import GeometricRender, PixelHits, geometric_render
from .passes import FIELD_OF_MODALITY, RenderOutput, cryptomatte_id, label_coverage, semantic_map


def rendered_modalities(outputs=()) -> tuple[str, ...]:
    """The modalities a render makes: those every ``render()`` holds (passes.FIELD_OF_MODALITY)
    and the ``render`` modalities ``outputs`` names, in table order; a one-line ValueError for
    an unknown name or a ``geometry`` one."""
    names = resolve(tuple(FIELD_OF_MODALITY) + (resolve(outputs) if outputs else ()))
    computed = [n for n in names if MODALITIES[n].source != "render"]
    if computed:
        raise ValueError(f"render() makes the render modalities; {', '.join(computed)} come from the geometry: "
                         "ask render_outputs() for them")
    return names


class ViewRenderer:
    """Renders views of one scene.

    ``pixel_truth`` casts the pixel-centre rays, ``pass_table`` maps Blender's Object Index
    pass to labels and instances (``ground_truth="renderer"``), ``label_of_part`` (P,) int32
    gives each part's label id and ``label_ids`` maps label names to ids. The Blender
    renderer (and its private folder of temporary files) is made at the first :meth:`render`;
    the folder is removed when the renderer is garbage-collected (with its Simulator).
    """

    def __init__(self, pixel_truth: PixelTruth, pass_table: PassTable, label_of_part: np.ndarray,
                 label_ids: dict[str, int]):
        self.pixel_truth = pixel_truth
        self.pass_table = pass_table
        self.label_of_part = label_of_part
        self.label_ids = label_ids
        self.renderer: Renderer | None = None
        self.cryptomatte_labels: dict[int, int] = {}  # Cryptomatte id -> label id, made with the renderer
        self.last_timings: dict[str, float] = {}  # seconds per stage of the last render()

    def hits(self, camera: CameraModel, world_from_camera: np.ndarray, normals: bool) -> PixelHits:
        """The surface at every pixel centre of the view (geometry/pixel_truth.py)."""
        return self.pixel_truth.hits(camera, world_from_camera, normals)

    def render(self, camera: CameraModel, world_from_camera: np.ndarray, frame: int,
               segmentation_sensitivity: float, ground_truth: str, outputs=(), normals: bool = False) -> RenderOutput:
        """One Blender render of the view (the scene's camera already at ``world_from_camera``),
        with depth, labels and ids from ``ground_truth`` ('geometry' or 'renderer') and the
        further ``render`` modalities ``outputs`` names (in ``extra``). The render has the
        passes of these modalities on and every other registered modality's off. With
        ``normals`` the cast beside Blender's render also finds the normals (kept for the
        geometry of this view)."""
        ground_truth = check_ground_truth(ground_truth)
        names = rendered_modalities(outputs)
        if self.renderer is None:
            self.renderer = Renderer()
            self.cryptomatte_labels = self._cryptomatte_labels()
        passes = blender_passes(names)
        off = [p for name, p in blender_passes().items() if name not in passes]
        # with ray-cast ground truth the pixel-centre cast runs while Blender renders; the
        # answer is kept by pixel_truth for _ground_truth_maps
        cast = (lambda: self.hits(camera, world_from_camera, normals)) if ground_truth == "geometry" or normals else None
        decoded = self.renderer.render(passes.values(), alongside=cast, off=off)
        t0 = time.perf_counter()
        arrays = {n: MODALITIES[n].from_render(decoded) for n in names if not MODALITIES[n].truth}
        arrays |= self._truth(decoded, camera, world_from_camera, segmentation_sensitivity, ground_truth)
        self.last_timings = dict(self.renderer.last_timings, labels=time.perf_counter() - t0)
        return RenderOutput.of({n: arrays[n] for n in names}, np.array(camera.K, dtype=np.float64),
                               np.array(world_from_camera, dtype=np.float64), int(frame))

    def _truth(self, decoded: dict, camera: CameraModel, world_from_camera: np.ndarray,
               segmentation_sensitivity: float, ground_truth: str) -> dict[str, np.ndarray]:
        """``depth``, ``label`` and ``instance`` from the ``ground_truth`` source, labels masked
        by the Cryptomatte coverage at ``segmentation_sensitivity`` where the render has it."""
        maps = self._ground_truth_maps(decoded, camera, world_from_camera, ground_truth)
        depth, index, label_of_index, instance_of_index = maps
        crypto, coverage = decoded[CRYPTO_OBJECT.name], None
        if crypto is not None:
            coverage = lambda seg: label_coverage(crypto, self.cryptomatte_labels, seg)  # noqa: E731
        sensitivity = segmentation_sensitivity if coverage is not None else 0.0
        seg, inst = semantic_map(index, label_of_index, instance_of_index, sensitivity, coverage)
        return {"depth": depth, "label": seg, "instance": inst}

    def _cryptomatte_labels(self) -> dict[int, int]:
        """Cryptomatte id -> label id of every Blender object (-2: a label the Simulator does
        not have, e.g. a filtered object's), ids computed from the names (passes.cryptomatte_id)."""
        return {cryptomatte_id(name): self.label_ids.get(label_of(name), -2) for name in objects_by_name()}

    def render_geometry(self, camera: CameraModel, world_from_camera: np.ndarray, frame: int,
                        normals: bool) -> GeometricRender:
        """The view by ray casting alone (no Blender render, no colour)."""
        hits = self.hits(camera, world_from_camera, normals)
        return geometric_render(hits, self.label_of_part, camera.K, world_from_camera, frame)

    def _ground_truth_maps(self, decoded: dict, camera: CameraModel, world_from_camera: np.ndarray,
                           ground_truth: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Planar depth and an object index (H, W) at the pixel centres, from the source
        ``ground_truth`` names, with the label and instance id of every index value
        (0: none). The renderer's Object Index pass gives instanced copies of one object one
        index (Blender's pass_index is per object); rays tell every copy apart (index = part
        + 1). Engines without an object-index pass get their index from the rays."""
        if ground_truth == "renderer" and decoded[OBJECT_INDEX.name] is not None:
            return decoded[DEPTH.name], decoded[OBJECT_INDEX.name], self.pass_table.labels, self.pass_table.instances
        hits = self.hits(camera, world_from_camera, normals=False)
        depth = hits.depth.copy() if ground_truth == "geometry" else decoded[DEPTH.name]
        parts = len(self.label_of_part)
        return (depth, (hits.part + 1).astype(np.int32), np.concatenate([[-1], self.label_of_part]).astype(np.int32),
                np.arange(-1, parts, dtype=np.int32))
