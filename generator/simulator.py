"""The paper's interactive API (section 3.1): ``from generator import Simulator``."""

from __future__ import annotations

import math
import os
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from .blender import session  # imports bpy first (before open3d)
from .blender import camera as bcam
from .blender.extract import assign_pass_indices, dynamic_matrices, extract_parts
from .blender.objects import SceneError, check_names, filtered_parts, object_table  # noqa: F401 (SceneError is public)
from .blender.objects import check_object_count
from .blender.render import RenderSettings, apply_settings, resolve_settings
from .blender.devices import active as active_device
from .checks import MAX_FRAME, Checked, check_flag, check_integer, check_number, check_seed
from .geometry import camera as cam_model
from .geometry.collision import move_is_allowed, position_is_free
from .geometry.observability import default_viewpoints, observable_mask
from .geometry.parts import MeshPart
from .geometry.pixel_truth import CameraModel, PixelTruth, check_ground_truth
from .geometry.raycam import GeometricRender, labels_of_parts
from .geometry.raycast import SceneGeometry
from .geometry.seeding import stream
from .geometry.spawn import respawn_pose, sample_spawn_points
from .geometry.surface_points import SurfacePoints
from .geometry.visibility import ViewLimits, VisibilityStats, visible_points
from .camera_moves import CameraMoves
from .image_sensor_api import ImageSensors
from .lens_api import Lenses
from .shutter_api import Shutters
from .lidar_api import LidarScans
from .paper_api import PaperAPI
from .passes import RenderOutput
from .view_render import ViewRenderer


class Simulator(CameraMoves, LidarScans, Lenses, ImageSensors, Shutters, PaperAPI):
    """A camera flying through a Blender scene, with ground-truth surface points.

    Units: metres, seconds, degrees where stated. Poses are OpenCV ``world_from_camera``
    4x4 matrices (x right, y down, z forward; world Z up). See docs/conventions.md.

    Args:
        blend_file: path to the .blend scene. Blender holds one file per process, so only
            the most recently created Simulator is usable.
        points_density: surface points sampled per square metre (> 0).
        segmentation_sensitivity: in [0, 1]; used by ``render()`` (the paper's figure 2).
        max_pcl_depth: points deeper than this planar depth (metres) are never visible.
        seed: seeds every random choice (point sampling, spawn points, respawns).
        collision_radius: radius in metres of the camera's collision sphere (finite, >= 0).
        render_preset: None keeps the .blend's render settings (engine, resolution,
            samples); 'preview', 'default' or 'high' override them (see configure_render).
        geometry_nodes_objects: the paper's objects to realise into meshes; accepted for
            its scripts, every object's instances and modifiers are realised anyway.
        filter_object_names: objects (by name) that get no surface points, no label and
            no collisions (they still render), as the paper's evaluation branch.
        instance_names: a fixed object table (unique names): instance id = index in it, in
            every output. It must hold every object of the scene; a name the scene lacks is
            an empty object (no triangles, no points, never seen) whose label is still in
            ``labels``. A timeline's stages share one table (generator/batch/phases.py), so
            instance and label ids do not change between stages.
            None (default): the scene's objects, sorted.
        ground_truth: where ``render()``'s depth, labels and instance ids come from:
            'geometry' (default) casts one ray per pixel centre into the scene's triangles
            (the same on every engine and device, and the surface the normals and flow
            describe); 'renderer' reads the renderer's passes (Cycles' Depth and Object
            Index, as the paper does). See docs/rendering.md.
        verbose: print what was found (points, labels) to stderr.

    The paper's names (``n_points``, ``camera_matrix``, ``set_camera_from_next_camera``...)
    work too: docs/simulator-api.md. ``scan(sensor)`` gives a LiDAR sweep from the camera
    (docs/lidar.md). Assigning ``max_pcl_depth``,
    ``segmentation_sensitivity``, ``collision_radius``, ``ground_truth`` or
    ``observed_points_mask`` later is checked as in the constructor.
    """

    # settable after construction, checked at every assignment (one-line ValueError)
    max_pcl_depth = Checked(lambda v: check_number("max_pcl_depth", v, 0, open_low=True, finite=False))
    segmentation_sensitivity = Checked(lambda v: check_number("segmentation_sensitivity", v, 0, 1))
    collision_radius = Checked(lambda v: check_number("collision_radius", v, 0))
    ground_truth = Checked(check_ground_truth)

    def __init__(
        self,
        blend_file: str | os.PathLike,
        points_density: float = 1.0,
        segmentation_sensitivity: float = 0.1,
        max_pcl_depth: float = math.inf,
        seed: int = 0,
        collision_radius: float = 0.3,
        render_preset: str | None = None,
        *,
        geometry_nodes_objects=("Generator",),
        filter_object_names=(),
        instance_names=None,
        ground_truth: str = "geometry",
        verbose: bool = False,
    ):
        self.points_density = check_number("points_density", points_density, 0, open_low=True)
        self.segmentation_sensitivity = segmentation_sensitivity
        self.max_pcl_depth = max_pcl_depth
        self.collision_radius = collision_radius
        self.seed = check_seed("seed", seed)
        self.blend_file = Path(blend_file)
        self.geometry_nodes_objects = check_names("geometry_nodes_objects", geometry_nodes_objects)
        self.filter_object_names = check_names("filter_object_names", filter_object_names)
        if instance_names is not None:
            instance_names = check_names("instance_names", instance_names)
        self.ground_truth = ground_truth
        self.verbose = check_flag("verbose", verbose)
        # every argument is checked before the file is loaded: loading replaces Blender's
        # scene, and with it the scene of any Simulator made before this one
        settings = resolve_settings(render_preset) if render_preset is not None else None
        check_object_count(self.blend_file)  # from the file's index, before loading it

        session.open_blend(self.blend_file)
        self._generation = session.generation()
        self._camera = bcam.scene_camera()
        bcam.detach_camera(self._camera)
        session.make_viewport_match_render()

        if settings is not None:
            apply_settings(settings)
        self._refresh_intrinsics()
        self.clip_start, self.clip_end = bcam.clip_range(self._camera)

        extracted = extract_parts()
        self._parts, self._bindings, self.labels = object_table(
            extracted, self.filter_object_names, instance_names, self.blend_file)
        self.label_ids = {name: i for i, name in enumerate(self.labels)}
        self.object_names: list[str] = [p.name for p in self._parts]
        self._geometry = SceneGeometry(self._parts)
        occluders, self._occluder_bindings = filtered_parts(extracted, self.filter_object_names)
        self._occluders = SceneGeometry(occluders) if occluders else None
        self._points = SurfacePoints(self._parts, self.label_ids, self.points_density, self.seed)
        # render() and render_geometry(): colour from Blender, ground truth from self.ground_truth
        self._views = ViewRenderer(PixelTruth(self._geometry, self._occluders),
                                   assign_pass_indices(self._parts, self.label_ids),
                                   labels_of_parts([p.label for p in self._parts], self.label_ids), self.label_ids)
        self.last_render_timings: dict[str, float] = {}  # seconds per stage of the last render()
        self._observed = np.zeros(len(self._points), dtype=bool)
        self._observable: np.ndarray | None = None  # observable_points_mask, computed on first use
        self.last_visibility = VisibilityStats()

        self._world_from_camera = bcam.read_pose(self._camera)
        self._initial_pose = self._world_from_camera.copy()
        self._respawn_rng = stream(self.seed, "respawn")
        self.spawn_points = (
            sample_spawn_points(extracted.spawn, self._geometry, self.collision_radius, stream(self.seed, "spawn"))
            if extracted.spawn is not None
            else self._initial_pose[None, :3, 3].copy()
        )
        self.frame = int(session.bpy.context.scene.frame_current)
        self._init_paper_api()
        if self.verbose:
            print(f"Found {self.n_static_points} static points and {self.n_dynamic_points} dynamic points; "
                  f"{self.n_labels} labels: {self.labels}", file=sys.stderr)

    # ---- state checks -------------------------------------------------------------------
    def _check_current(self) -> None:
        if self._generation != session.generation():
            raise RuntimeError("another Simulator (or file) was loaded since this one; Blender holds one scene per process")

    # ---- scene facts ---------------------------------------------------------------------
    @property
    def num_points(self) -> int:
        return len(self._points)

    @property
    def point_positions(self) -> np.ndarray:
        """(N, 3) float64 world metres of the surface points at the current frame (read-only)."""
        return self._points.world

    @property
    def scene(self):
        """Blender's scene (bpy). Set the camera with the Simulator's methods, not here."""
        self._check_current()
        return session.bpy.context.scene

    @property
    def view_layer(self):
        """Blender's view layer (bpy)."""
        self._check_current()
        return session.bpy.context.view_layer

    @property
    def camera(self):
        """Blender's camera object (bpy). Its pose is written by the Simulator; moving it
        directly is not seen by the Simulator (use ``set_world_from_camera``)."""
        self._check_current()
        return self._camera

    @property
    def observed_points_mask(self) -> np.ndarray:
        """(N,) bool: the point was visible in some ``compute_point_cloud`` call so far (within
        ``max_pcl_depth``); assign an (N,) array of bools to set it (the paper resets it so)."""
        return self._observed

    @observed_points_mask.setter
    def observed_points_mask(self, mask) -> None:
        m = np.asarray(mask)
        if m.shape != (len(self._points),) or m.dtype != bool:
            raise ValueError(f"observed_points_mask must be an ({len(self._points)},) array of bools (one per "
                             f"point), got {m.dtype} {m.shape}")
        # the caller's array itself when it is one (later observations show in it, as before)
        self._observed = mask if isinstance(mask, np.ndarray) and mask.flags.writeable else m.copy()

    @property
    def point_instances(self) -> np.ndarray:
        """(N,) int32 index into ``object_names`` of the object each point lies on."""
        return self._points.part.copy()

    @property
    def dynamic_points_mask(self) -> np.ndarray:
        """(N,) bool: the point lies on a moving object."""
        return self._points.dynamic_mask

    @property
    def dynamic_objects(self) -> list[str]:
        return [p.name for p in self._parts if p.dynamic]

    def point_table(self) -> dict:
        """The point set as stored in exports: ``local`` (N, 3) metres (world for static
        points, object frame for dynamic ones), ``labels``, ``instance`` (N,) int32,
        ``dynamic_object`` (N,) int32 index into ``dynamic_objects`` (-1: static)."""
        return self._points.table()

    def scene_parts(self) -> list[MeshPart]:
        """Copies of the scene's rigid parts (static in world coordinates, dynamic in their
        object frame with the current frame's matrix), in ``object_names`` order."""
        return [replace(p, vertices=p.vertices.copy(), faces=p.faces.copy(), matrix=p.matrix.copy()) for p in self._parts]

    def surface_sample(self) -> dict:
        """The surface points as the visibility rules need them: ``local`` (N, 3) and
        ``local_normals`` (N, 3) (outward unit normals on closed parts, zero elsewhere) in
        the part's frame, ``part`` (N,) int32 index into ``object_names``, ``labels`` (N,)."""
        return self._points.sample()

    @property
    def frame_range(self) -> tuple[int, int]:
        """First and last frame of the scene's animation (inclusive)."""
        self._check_current()
        scene = session.bpy.context.scene
        return int(scene.frame_start), int(scene.frame_end)

    @property
    def fps(self) -> float:
        """Animation frames per second."""
        self._check_current()
        r = session.bpy.context.scene.render
        return float(r.fps) / float(r.fps_base)

    def dynamic_object_matrices(self) -> np.ndarray:
        """(D, 4, 4) world_from_object of the ``dynamic_objects`` at the current frame."""
        return np.stack([p.matrix for p in self._parts if p.dynamic]) if self.dynamic_objects else np.zeros((0, 4, 4))

    @property
    def observable_points_mask(self) -> np.ndarray:
        """(N,) bool: the point is visible from at least one of the observability viewpoints
        (spawn points) in some direction, with no depth limit, dynamic objects at the first
        animation frame (generator/geometry/observability.py). Computed on first use, cached."""
        if self._observable is None:
            frame, first = self.frame, self.frame_range[0]
            self.set_frame(first)
            try:
                pts = self._points
                self._observable = observable_mask(self._geometry, pts.world, pts.world_normals, pts.part,
                                                   default_viewpoints(self.spawn_points))
            finally:
                self.set_frame(frame)
        return self._observable.copy()

    @property
    def coverage(self) -> float:
        """Share of all surface points observed at least once (0 to 1)."""
        n = len(self.observed_points_mask)
        return float(self.observed_points_mask.sum()) / n if n else 0.0

    # ---- point cloud ---------------------------------------------------------------------
    def compute_point_cloud(self, update_mask: bool = True, imshow: bool = False,
                            max_depth: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All surface points at the current frame and which ones the camera sees.

        Returns ``(points (N, 3) float64 world metres, labels (N,) int32, visible (N,) bool)``.
        ``points`` and ``labels`` are read-only and are not modified by later calls (copy
        them to edit). With ``update_mask`` the visible points are added to
        ``observed_points_mask``. With ``imshow`` the visible points are drawn in their
        ``point_cloud_colors`` into ``point_cloud_image`` ((H, W, 3) uint8; no window opens).
        ``max_depth`` (metres, planar) replaces ``max_pcl_depth`` for this call only
        (``math.inf``: every depth the camera renders, up to its clip end).
        """
        self._check_current()
        update_mask, imshow = check_flag("update_mask", update_mask), check_flag("imshow", imshow)
        limit = (self.max_pcl_depth if max_depth is None
                 else check_number("max_depth", max_depth, 0, open_low=True, finite=False))
        pts = self._points
        visible = visible_points(
            self._geometry, pts.world, pts.world_normals, pts.part, self._world_from_camera, self.K,
            self.width, self.height, ViewLimits(self.clip_start, min(self.clip_end, limit)), self.last_visibility,
            lens=self.lens,
        )
        if update_mask:
            self._observed |= visible
        if imshow:
            self.point_cloud_image = self.draw_point_cloud_image(visible)
        return pts.world, pts.labels, visible

    def reset_observations(self) -> None:
        """Forget the observation history (coverage back to 0)."""
        self._observed[:] = False

    def depth_to_world_points(self, depth: np.ndarray) -> np.ndarray:
        """Unproject a planar depth map (H, W) in metres from the current pose to world
        points (H, W, 3); pixels without a surface (inf) give NaN."""
        depth = np.asarray(depth)
        if depth.shape != (self.height, self.width):
            raise ValueError(f"depth must have shape {(self.height, self.width)}, got {depth.shape}")
        return cam_model.depth_to_world_points(depth, self.K, self._world_from_camera, self.lens)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (N, 3) in metres -> (pixel coordinates (N, 2) float64 as (x, y), with the
        top-left pixel's centre at (0.5, 0.5); planar depths (N,) float64 in metres, <= 0
        behind the camera) at the current pose, through the camera's lens (:meth:`set_lens`;
        with a distorting lens, points behind the camera give NaN pixels). Occlusion and the
        image bounds are ignored."""
        try:
            p = np.asarray(points, dtype=np.float64)
        except (TypeError, ValueError):
            p = None
        if p is None or p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points must be an (N, 3) array of world coordinates in metres, got "
                             f"{'shape ' + str(p.shape) if p is not None else repr(points)[:60]}")
        return cam_model.project(p, self._world_from_camera, self.K, self.lens)

    # ---- camera --------------------------------------------------------------------------
    def get_world_from_camera(self) -> np.ndarray:
        """Current camera pose, OpenCV ``world_from_camera`` (4x4, metres)."""
        return self._world_from_camera.copy()

    def is_free(self, position) -> bool:
        """True if the camera sphere fits at ``position`` (3,) without touching geometry."""
        self._check_current()
        return position_is_free(self._geometry, position, self.collision_radius)

    def can_move(self, start, end) -> bool:
        """True if the camera sphere can travel in a straight line from ``start`` to ``end``
        (a camera that starts touching geometry may still move away to a free position:
        generator/geometry/collision.py ``move_is_allowed``)."""
        self._check_current()
        return move_is_allowed(self._geometry, start, end, self.collision_radius)

    def set_world_from_camera(self, matrix, check_collisions: bool = True) -> bool:
        """Move the camera to a pose; returns True (and leaves the pose unchanged) if the
        straight move from the current position collides."""
        self._check_current()
        m = cam_model.validate_rigid(matrix)
        if check_flag("check_collisions", check_collisions) and not self.can_move(self._world_from_camera[:3, 3], m[:3, 3]):
            return True
        self._world_from_camera = m.copy()
        bcam.write_pose(m, self._camera)
        return False

    def respawn_camera(self) -> np.ndarray:
        """Move the camera to a random free spawn point with a random heading (pitch kept,
        roll zero). Without a CameraSpawn volume, return to the initial pose. Returns the pose."""
        self._check_current()
        if self.spawn_points.shape[0] == 1 and np.allclose(self.spawn_points[0], self._initial_pose[:3, 3]):
            self.set_world_from_camera(self._initial_pose, check_collisions=False)
            return self.get_world_from_camera()
        pose = respawn_pose(self.spawn_points, self._world_from_camera, self._respawn_rng, self.is_free)
        self.set_world_from_camera(pose, check_collisions=False)
        return self.get_world_from_camera()

    # ---- time ----------------------------------------------------------------------------
    def set_frame(self, frame: int) -> int:
        """Jump to animation ``frame``; dynamic objects and their points move there."""
        self._check_current()
        if isinstance(frame, (float, np.floating)) and float(frame).is_integer():
            frame = int(frame)  # 3.0 is frame 3, as it always was; 1.5 is refused
        self.frame = check_integer("frame", frame, -MAX_FRAME, MAX_FRAME)
        session.set_frame(self.frame)
        self._geometry.set_matrices(dynamic_matrices(self._bindings))
        if self._occluders is not None:
            self._occluders.set_matrices(dynamic_matrices(self._occluder_bindings))
        self._points.update(self._parts)
        bcam.write_pose(self._world_from_camera, self._camera)
        return self.frame

    def step_frame(self) -> int:
        """Advance the animation by one frame; dynamic objects and their points move.
        Returns the new frame number."""
        return self.set_frame(self.frame + 1)

    # ---- rendering -----------------------------------------------------------------------
    def _refresh_intrinsics(self) -> None:
        intr = bcam.read_intrinsics(self._camera)
        self.width, self.height, self.K = intr.width, intr.height, intr.K
        if not self.lens.ideal:  # the lens's shader holds K and the image size
            self._apply_lens(self.lens)

    def configure_render(self, preset: str | None = None, **overrides) -> RenderSettings:
        """Set render quality: a preset ('preview', 'default', 'high') and/or explicit
        ``engine``, ``samples``, ``denoise``, ``denoise_prefilter``, ``bounces``,
        ``threads``, ``resolution=(width, height)``, ``denoise_quality``, ``light_tree``,
        ``adaptive_threshold``, ``device`` ('cpu', 'gpu' or 'auto': a CUDA/OptiX GPU when
        there is one; 'gpu' without one raises DeviceUnavailableError; see
        ``render_device``). Changing the resolution changes ``K``, ``width`` and ``height``
        (visibility uses the new image too)."""
        self._check_current()
        settings = resolve_settings(preset, **overrides)
        apply_settings(settings)
        self._refresh_intrinsics()
        return settings

    @property
    def render_device(self) -> str:
        """What Cycles renders on: 'CPU', or the GPU backend and names (e.g. 'OPTIX: NVIDIA ...')."""
        self._check_current()
        return active_device()

    @property
    def instance_table(self) -> list[dict]:
        """Rows ``{"id", "object", "label", "label_id"}`` for the ids in ``render().instance``."""
        return [
            {"id": i, "object": p.name, "label": p.label, "label_id": self.label_ids[p.label]}
            for i, p in enumerate(self._parts)
        ]

    def render_outputs(self, names=None, poses=None, object_matrices=None, index: int = 0) -> RenderOutput:
        """The modalities ``names`` of the current view (default: all of
        ``exporters.modalities.MODALITIES``: rgb, rgb_linear, depth, label, instance, normal,
        flow, backward_flow), keyed by name (``out["flow"]``). Flow needs the trajectory:
        ``poses`` (T, 4, 4) and ``object_matrices`` (T, D, 4, 4) of ``dynamic_objects`` at
        every frame, this view being frame ``index`` (see generator/frame_outputs.py)."""
        from .frame_outputs import render_outputs

        return render_outputs(self, names, poses, object_matrices, index)

    def render(self, engine: str | None = None, outputs=(), normals: bool = False) -> RenderOutput:
        """Render the current view: ``rgb, depth, seg = sim.render()`` (one Blender render).

        See :class:`generator.passes.RenderOutput` for shapes, units and conventions; the
        returned object also holds ``instance`` and ``rgb_linear``. Depth, labels and ids come
        from ``ground_truth`` (default: ray casting the scene's triangles at the pixel centres,
        the same on every device); colour from Blender. ``engine="raycast"`` returns
        :meth:`render_geometry` instead (no Blender render, no RGB). ``outputs``: further
        ``render`` modalities (exporters/modalities.py) to render, by name, into ``out.extra``.
        ``normals``: the pixel-centre cast that runs while Blender renders also finds the
        normals, kept for :meth:`render_geometry` of this view (which then casts nothing).
        """
        if engine == "raycast":
            return self.render_geometry()
        if engine is not None:
            raise ValueError(f"engine must be None (the scene's Blender engine) or 'raycast', got {engine!r}")
        self._check_current()
        self._check_rolling_view()
        out = self._views.render(self._camera_model(), self._world_from_camera, self.frame,
                                 self.segmentation_sensitivity, self.ground_truth, outputs,
                                 check_flag("normals", normals))
        self.last_render_timings = dict(self._views.last_timings)
        return self._sense(out)

    def render_geometry(self, normals: bool = True) -> GeometricRender:
        """The current view by ray casting the Simulator's geometry, one ray per pixel centre,
        no Blender render: depth, seg and instance with the conventions of :meth:`render`
        (``segmentation_sensitivity`` 0), ``normal`` (H, W, 3) camera-frame unit normals
        facing the camera (None without ``normals``), and ``rgb`` = ``rgb_linear`` = None
        (colour needs a renderer). Objects in ``filter_object_names`` are unlabelled surfaces
        (seg and instance -1, depth and normal kept). See generator/geometry/pixel_truth.py."""
        self._check_current()
        return self._views.render_geometry(self._camera_model(), self._world_from_camera, self.frame,
                                           check_flag("normals", normals))

    def _camera_model(self) -> CameraModel:
        return CameraModel(self.K, self.width, self.height, self.clip_start, self.clip_end, self.lens)
