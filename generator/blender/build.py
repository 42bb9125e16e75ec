"""Turn a :class:`generator.scene.site.SitePlan` into a Blender scene and save it."""

from __future__ import annotations

import json
import math

import bpy
import numpy as np
from bpy_extras import anim_utils

from ..geometry.camera import SITE_LENS_MM, SITE_SENSOR_MM
from ..geometry.portable_math import atan2, hypot, sincos
from ..scene.assets import Asset
from ..scene.kinds import kind as kind_named
from ..scene.meshes import MeshData
from ..scene.site import SitePlan, fence_part, site_ground, split_margin, wet_materials
from ..scene.timeline import object_name
from ..scene.taxonomy import CLASSES
from . import session
from .extract import SCENERY_PROPERTY
from .materials import make_material
from .render import apply_settings, resolve_settings
from .season import apply_season
from .sky import build_sky

LABEL_TABLE_PROPERTY = "buildee_labels"
SITE_PROPERTY = "buildee_site"


def mesh_from_data(name: str, data: MeshData, seed: int):
    """A Blender mesh from quads and triangles (fast path through foreach_set)."""
    me = bpy.data.meshes.new(name)
    nq, nt = len(data.quads), len(data.tris)
    me.vertices.add(len(data.vertices))
    me.vertices.foreach_set("co", data.vertices.astype(np.float32).ravel())
    loops = np.concatenate([data.quads.ravel(), data.tris.ravel()]).astype(np.int32)
    me.loops.add(len(loops))
    me.loops.foreach_set("vertex_index", loops)
    me.polygons.add(nq + nt)
    me.polygons.foreach_set("loop_start", np.concatenate([np.arange(nq) * 4, nq * 4 + np.arange(nt) * 3]).astype(np.int32))
    me.polygons.foreach_set("material_index", data.face_material.astype(np.int32))
    me.update(calc_edges=True)
    for key in data.materials:
        me.materials.append(make_material(key, seed))
    return me


def _insert_linear_keys(obj, frames: np.ndarray, channels: dict) -> None:
    """Linear keyframes on ``obj``: for each data path in ``channels`` (values (K, 3) at
    ``frames`` (K,)), one F-curve per component. One keyframe_insert per path creates the
    action, slot and F-curves; the remaining keys are written in bulk (keyframe_insert per
    frame costs more than linear time in the frame count)."""
    for path, values in channels.items():
        setattr(obj, path, tuple(values[0]))
        obj.keyframe_insert(path, frame=float(frames[0]))
    ad = obj.animation_data
    bag = anim_utils.action_get_channelbag_for_slot(ad.action, ad.action_slot)
    for fc in bag.fcurves:
        values = channels.get(fc.data_path)
        if values is None:
            continue
        co = np.empty(2 * len(frames), dtype=np.float64)
        co[0::2], co[1::2] = frames, values[:, fc.array_index]
        fc.keyframe_points.add(len(frames) - len(fc.keyframe_points))
        fc.keyframe_points.foreach_set("co", co)
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"
        fc.update()


def _collection(name: str):
    coll = bpy.data.collections.get(name)
    if coll is None:
        coll = bpy.data.collections.new(name)
        bpy.context.scene.collection.children.link(coll)
    return coll


def add_asset(asset: Asset, position, yaw: float, seed: int, collection, index: int = -1, uid: int | None = None) -> list:
    """Create the asset's objects; root parts are placed at ``position`` / ``yaw``. With a
    ``uid`` (a timeline's stage) objects get the names they have in every stage."""
    objects = []
    s, c = sincos(yaw)
    px, py = position
    try:
        scenery = kind_named(asset.kind).scenery
    except KeyError:  # an asset of no registered kind
        scenery = False
    for number, part in enumerate(asset.parts):
        name = part.label or f"{asset.kind}Pivot"
        if uid is not None:
            name = object_name(name, uid, number)
        data = mesh_from_data(name, part.mesh, seed) if part.mesh is not None else None
        obj = bpy.data.objects.new(name, data)
        collection.objects.link(obj)
        obj.rotation_mode = "XYZ"
        root = part.parent is None

        def place(loc, rot):
            if not root:
                return loc, rot
            if abs(rot[0]) > 1e-12 or abs(rot[1]) > 1e-12:
                raise ValueError(f"root part of {asset.kind} must only turn about z")
            return (c * loc[0] - s * loc[1] + px, s * loc[0] + c * loc[1] + py, loc[2]), (0.0, 0.0, rot[2] + yaw)

        loc, rot = place(part.location, part.rotation)
        if part.parent is not None:
            obj.parent = objects[part.parent]
        if part.keys is not None:
            k = part.keys
            placed = [place(tuple(k.location[i] if k.location is not None else part.location),
                            tuple(k.rotation[i] if k.rotation is not None else part.rotation))
                      for i in range(len(k.frames))]
            channels = {"location": np.array([p[0] for p in placed], dtype=np.float64),
                        "rotation_euler": np.array([p[1] for p in placed], dtype=np.float64)}
            keyed = [path for path, given in (("location", k.location), ("rotation_euler", k.rotation))
                     if given is not None]
            _insert_linear_keys(obj, np.asarray(k.frames, dtype=np.float64), {p: channels[p] for p in keyed})
            if k.location is None:  # channels without keys keep the rest transform
                obj.location = loc
            if k.rotation is None:
                obj.rotation_euler = rot
        else:
            obj.location, obj.rotation_euler = loc, rot
        if data is None:
            obj.empty_display_size = 1.0
        obj["buildee_group"] = asset.kind
        if scenery or part.scenery:
            obj[SCENERY_PROPERTY] = True  # rendered, no surface points (generator/geometry/parts.py MeshPart.scenery)
        obj["buildee_asset"] = index  # which placed asset the object belongs to (-1: ground, fence)
        objects.append(obj)
    return objects


def build_in_blender(plan: SitePlan, resolution: tuple[int, int] = (640, 480)) -> dict:
    """Replace the open file with the planned site; returns counts per class."""
    session.new_empty_file()
    scene = bpy.context.scene
    p = plan.params
    scene.frame_start, scene.frame_end = 1, p.frames
    scene.render.fps = int(round(p.fps))
    scene.render.fps_base = scene.render.fps / p.fps
    scene.unit_settings.system = "METRIC"
    seed = plan.seed
    timeline = plan.stages > 1  # stable object names over the stages (docs/phases.md)
    with session.quiet():
        ground = site_ground(plan)
        add_asset(Asset("Ground", list(split_margin(ground, p.size / 2)), (p.size, p.size)), (0.0, 0.0), 0.0, seed,
                  _collection("Ground"),
                  uid=0 if timeline else None)
        fences = [fence_part(a, b) for a, b in plan.fence_runs]
        add_asset(Asset("Fence", fences, (0.0, 0.0)), (0.0, 0.0), 0.0, seed, _collection("Fence"), uid=0 if timeline else None)
        for index, placed in enumerate(plan.placed):
            add_asset(placed.asset, placed.position, placed.yaw, seed, _collection(placed.asset.kind), index,
                      uid=placed.uid if timeline else None)
        build_sky(plan.weather, [make_material(m, seed) for m in wet_materials(ground)])
        apply_season(plan.weather.season, plan.weather.snow_cover)
        lo, hi = plan.spawn_box
        spawn = bpy.data.objects.new("CameraSpawn", mesh_from_data("CameraSpawn", _box_data(lo, hi), seed))
        scene.collection.objects.link(spawn)
        spawn.hide_render = True
        spawn.display_type = "WIRE"
        cam_data = bpy.data.cameras.new("Camera")
        cam_data.lens, cam_data.sensor_width, cam_data.clip_start, cam_data.clip_end = SITE_LENS_MM, SITE_SENSOR_MM, 0.1, 2000.0
        cam = bpy.data.objects.new("Camera", cam_data)
        scene.collection.objects.link(cam)
        eye, target = (np.array(v, dtype=float) for v in plan.camera)
        d = target - eye
        cam.rotation_euler = (atan2(hypot(d[0], d[1]), -d[2]), 0.0, atan2(d[1], d[0]) - math.pi / 2)
        cam.location = tuple(eye)
        scene.camera = cam
        apply_settings(resolve_settings("default", resolution=resolution))
        scene.frame_set(1)
    scene[LABEL_TABLE_PROPERTY] = json.dumps(list(CLASSES))
    summary = plan.summary()
    scene[SITE_PROPERTY] = json.dumps(summary, default=float)
    counts: dict[str, int] = {}
    triangles = 0
    for obj in bpy.data.objects:
        if obj.type == "MESH" and obj.name != "CameraSpawn":
            label = obj.name.split(".")[0]
            counts[label] = counts.get(label, 0) + 1
            obj.data.calc_loop_triangles()
            triangles += len(obj.data.loop_triangles)
    return {"objects_per_class": dict(sorted(counts.items())), "triangles": triangles, "objects": sum(counts.values())}


def _box_data(lo, hi) -> MeshData:
    from ..scene.meshes import MeshBuilder

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return MeshBuilder().box(hi - lo, (lo + hi) / 2).build()
