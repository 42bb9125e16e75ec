"""The paper's Simulator names on ours (its repository's ``buildee/simulator.py``).

:class:`PaperAPI` is a mixin of :class:`generator.Simulator`: every public method and
attribute of the paper's Simulator that has a meaning here, under the paper's name, built
on our public API. docs/simulator-api.md is the full table (paper name | ours | note),
with what we leave out and why.
"""

from __future__ import annotations

import numpy as np

from .geometry import camera as cam_model


class PaperAPI:
    """Aliases and small additions with the paper's names and meanings (bpy-free)."""

    # ---- counts ---------------------------------------------------------------------------
    @property
    def n_points(self) -> int:
        """Number of surface points (the paper's ``n_points``; ours ``num_points``)."""
        return self.num_points

    @property
    def n_static_points(self) -> int:
        return int(np.count_nonzero(~self.dynamic_points_mask))

    @property
    def n_dynamic_points(self) -> int:
        return int(np.count_nonzero(self.dynamic_points_mask))

    @property
    def n_static_vertices(self) -> int:
        """Mesh vertices of the static objects (evaluated, instances realised)."""
        return sum(len(p.vertices) for p in self.scene_parts() if not p.dynamic)

    @property
    def n_dynamic_vertices(self) -> int:
        return sum(len(p.vertices) for p in self.scene_parts() if p.dynamic)

    @property
    def n_vertices(self) -> int:
        return sum(len(p.vertices) for p in self.scene_parts())

    @property
    def n_labels(self) -> int:
        """Number of labels (``len(labels)``)."""
        return len(self.labels)

    # ---- objects and their points --------------------------------------------------------
    @property
    def objects(self) -> dict[str, bool]:
        """Object name -> True if it moves (the paper maps bpy objects to ``is_animated``)."""
        return {p.name: p.dynamic for p in self.scene_parts()}

    @property
    def object_labels(self) -> dict[str, str]:
        """Object name -> label (its name without Blender's ``.NNN`` suffix)."""
        return {row["object"]: row["label"] for row in self.instance_table}

    def _object_point_clouds(self, dynamic: bool) -> dict[str, np.ndarray]:
        table = self.point_table()
        names, moving = self.object_names, self.objects
        return {name: table["local"][table["instance"] == i] for i, name in enumerate(names) if moving[name] == dynamic}

    @property
    def static_point_clouds(self) -> dict[str, np.ndarray]:
        """Object name -> (n, 3) surface points of each static object, world metres."""
        return self._object_point_clouds(False)

    @property
    def dynamic_point_clouds(self) -> dict[str, np.ndarray]:
        """Object name -> (n, 3) surface points of each moving object, in its object frame."""
        return self._object_point_clouds(True)

    @property
    def point_cloud_colors(self) -> np.ndarray:
        """(N, 3) uint8 display colours of the points: each point's world position at
        construction, scaled to [0, 255] per axis over the cloud (the paper's rule)."""
        return self._paper_colours.copy()

    def _init_paper_api(self) -> None:
        """Called by the constructor once the points exist."""
        xyz = np.array(self.point_positions, dtype=np.float64)
        lo = xyz.min(axis=0) if len(xyz) else np.zeros(3)
        span = xyz.max(axis=0) - lo if len(xyz) else np.ones(3)
        self._paper_colours = np.uint8((xyz - lo) / np.where(span > 0, span, 1.0) * 255)
        self.point_cloud_image: np.ndarray | None = None

    # ---- camera ---------------------------------------------------------------------------
    @property
    def camera_matrix(self) -> np.ndarray:
        """3x3 intrinsics K in pixels (the current resolution; ours ``K``)."""
        return self.K.copy()

    def get_camera_matrix(self) -> np.ndarray:
        """3x3 intrinsics K in pixels."""
        return self.K.copy()

    def set_camera_from_next_camera(self, camera_from_next_camera) -> bool:
        """Move the camera by a 4x4 rigid transform expressed in its own frame (OpenCV axes):
        the new pose is ``world_from_camera @ camera_from_next_camera``. Returns True (and
        does not move) if the straight move collides."""
        step = cam_model.validate_rigid(camera_from_next_camera)
        return self.set_world_from_camera(cam_model.matmul_exact(self.get_world_from_camera(), step))

    def draw_point_cloud_image(self, visible: np.ndarray) -> np.ndarray:
        """(H, W, 3) uint8: ``point_cloud_colors`` of the ``visible`` points at their pixels,
        black elsewhere (what the paper's ``imshow`` displays)."""
        pts = np.asarray(self.point_positions)[visible]
        xy, _ = self.project(pts)
        img = np.zeros((self.height, self.width, 3), dtype=np.uint8)
        col = np.clip(np.floor(xy[:, 0]).astype(np.int64), 0, self.width - 1)
        row = np.clip(np.floor(xy[:, 1]).astype(np.int64), 0, self.height - 1)
        img[row, col] = self._paper_colours[visible]
        return img
