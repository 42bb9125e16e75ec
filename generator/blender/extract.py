"""Turn the evaluated Blender scene into rigid mesh parts (numpy), with labels and motion.

Every object instance the render camera sees that yields triangles (meshes, curves, text,
metaballs; modifiers, geometry nodes and instancing evaluated) becomes one :class:`MeshPart`.
Objects hidden from camera rays (Visibility > Camera off, or in an indirect-only collection)
are left out; holdouts and motion the parts cannot follow are refused (``refusal``); see
docs/rendering.md, "What of a .blend is honoured".
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import bpy
import numpy as np

from ..geometry.camera import affine_inverse, apply_affine, matmul_exact
from ..geometry.parts import MeshPart, closed_and_orientation
from .animation import animated_visibility, deforming, dynamic_object_names, moves_within
from .keys import instance_key, object_key

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
SPAWN_LABEL = "CameraSpawn"
SCENERY_PROPERTY = "buildee_scenery"  # an object property: the object is scenery (MeshPart.scenery)
# material properties: its LiDAR optics (MeshPart.face_reflectivity / face_transparent); a
# material without them (a user's) reflects DEFAULT_REFLECTIVITY and is opaque
REFLECTIVITY_PROPERTY = "buildee_reflectivity"
TRANSPARENT_PROPERTY = "buildee_transparent"
_SUFFIX = re.compile(r"\.\d{3,}$")


def label_of(name: str) -> str:
    """Semantic label of an object: its name without Blender's ``.NNN`` duplicate suffix."""
    return _SUFFIX.sub("", name)


@dataclass
class DynamicBinding:
    """How to recompute a dynamic part's matrix at another frame.

    world_from_object(t) = world(driver, t) @ offset [@ world(source, t)], where ``driver`` is
    the object whose evaluated matrix moves the part (the object itself, or the instancer of an
    instance) and ``source``, for a collection instance of a moving object, that object (by name;
    ``driver_object`` and ``source_object`` are those Blender objects, found once at load).
    """

    part: int
    driver: str
    offset: np.ndarray
    source: str | None = None
    driver_object: object = field(default=None, repr=False, compare=False)
    source_object: object = field(default=None, repr=False, compare=False)


def _mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(vertices, triangles, each triangle's reflectivity, each triangle's transparency)."""
    nv = len(mesh.vertices)
    co = np.empty(nv * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", co)
    mesh.calc_loop_triangles()
    nt = len(mesh.loop_triangles)
    tri = np.empty(nt * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tri)
    slot = np.zeros(nt, dtype=np.int32)
    mesh.loop_triangles.foreach_get("material_index", slot)
    reflectivity, transparent = _slot_optics(mesh.materials)
    slot = np.clip(slot, 0, len(reflectivity) - 1)
    return co.reshape(nv, 3), tri.reshape(nt, 3), reflectivity[slot], transparent[slot]


def _slot_optics(materials) -> tuple[np.ndarray, np.ndarray]:
    """(reflectivity (S,) float32, transparent (S,) bool) of a mesh's material slots (one
    default slot if it has none)."""
    from ..lidar.physics import DEFAULT_REFLECTIVITY

    rows = [(float(m.get(REFLECTIVITY_PROPERTY, DEFAULT_REFLECTIVITY)), bool(m.get(TRANSPARENT_PROPERTY, False)))
            if m is not None else (DEFAULT_REFLECTIVITY, False) for m in materials] or [(DEFAULT_REFLECTIVITY, False)]
    return np.array([r for r, _ in rows], dtype=np.float32), np.array([t for _, t in rows], dtype=bool)


def _evaluated_mesh(obj, cache: dict):
    """(vertices, faces, closed, outward, face reflectivity, face transparency) of an
    evaluated object, cached per mesh datablock."""
    data = obj.data
    key = data.as_pointer() if (obj.type == "MESH" and data is not None) else None
    if key is not None and key in cache:
        return cache[key]
    if obj.type == "MESH":
        verts, faces, reflectivity, transparent = _mesh_arrays(data)
    else:
        mesh = obj.to_mesh()
        try:
            verts, faces, reflectivity, transparent = _mesh_arrays(mesh) if mesh is not None else (
                np.zeros((0, 3)), np.zeros((0, 3), np.int32), np.zeros(0, np.float32), np.zeros(0, bool))
        finally:
            obj.to_mesh_clear()
    closed, outward = closed_and_orientation(verts, faces) if len(faces) and np.isfinite(verts).all() else (False, 1)
    result = (verts, faces, closed, outward, reflectivity, transparent)
    if key is not None:
        cache[key] = result
    return result


def _matrix(m) -> np.ndarray:
    return np.array(m, dtype=np.float64)


def _hidden_spawn_volume() -> MeshPart | None:
    """A CameraSpawn mesh that is not rendered (the usual case) is absent from the evaluated
    scene: read its own mesh data (modifiers are not applied to spawn volumes)."""
    for obj in sorted(bpy.data.objects, key=lambda o: o.name):
        if obj.type == "MESH" and label_of(obj.name) == SPAWN_LABEL and len(obj.data.polygons):
            verts, faces = _mesh_arrays(obj.data)[:2]
            world = _matrix(obj.matrix_world)
            wv = apply_affine(world, verts)  # BLAS-free: the same bits on every CPU
            c, o = closed_and_orientation(wv, faces)
            return MeshPart(obj.name, SPAWN_LABEL, wv, faces.copy(), closed=c, outward=o)
    return None


@dataclass
class ExtractedScene:
    parts: list[MeshPart]
    bindings: list[DynamicBinding]
    spawn: MeshPart | None
    refusal: str | None = None  # one line: why this scene cannot be simulated (objects.object_table raises it)


@dataclass
class _LayerFlags:
    """Objects of the view layer in an indirect-only or holdout collection (or holdout themselves)."""

    indirect_only: set[str]
    holdout: set[str]

    @staticmethod
    def of(view_layer) -> "_LayerFlags":
        objs = list(view_layer.objects)
        return _LayerFlags({o.name for o in objs if o.indirect_only_get(view_layer=view_layer)},
                           {o.name for o in objs if o.holdout_get(view_layer=view_layer)})


def _anchor(inst):
    """The object whose view-layer flags apply: the instancer of an instance, else the object."""
    return _original(inst.parent) if inst.is_instance else _original(inst.object)


def _camera_sees(inst, flags: _LayerFlags) -> bool:
    """Cycles' rule: the object and its instancer visible to camera rays, the instancer (the
    object itself when not an instance) not in an indirect-only collection."""
    anchor = _anchor(inst)
    return _original(inst.object).visible_camera and anchor.visible_camera and anchor.name not in flags.indirect_only


def _original(obj):
    return obj.original if obj.original is not None else obj


def _hidden_instancer_child(obj) -> bool:
    """Renders hide the original of an object instanced on its parent's vertices or faces
    (the viewport shows it); metaballs keep it."""
    parent = obj.parent
    return obj.type != "META" and parent is not None and parent.instance_type in ("VERTS", "FACES")


def _particles_move(psys, scene) -> bool:
    """Particle copies that move, appear or die during the scene's frames (the copies are
    taken once at load): emitter particles with physics, or born or dying in the frame range;
    hair with dynamics."""
    s = psys.settings
    if s.type == "HAIR":
        return bool(psys.use_hair_dynamics)
    shortest = s.lifetime * (1.0 - s.lifetime_random)
    born_later = s.frame_end > scene.frame_start and not s.show_unborn  # unborn copies are drawn where they will be
    dying = s.frame_start + shortest < scene.frame_end and not s.use_dead  # dead copies are drawn where they died
    return s.physics_type != "NO" or born_later or dying


def _instance_motion(inst, source, instancer, dynamic: set[str], memo: dict):
    """(source object name to bind, or None; refusal or None) for an instance whose source
    object may move relative to its instancer."""
    key = (source.name, instancer.name)
    if key not in memo:
        memo[key] = source.name in dynamic and moves_within(source, instancer)
    if not memo[key]:
        return None, None
    coll = instancer.instance_collection if instancer.instance_type == "COLLECTION" else None
    if coll is not None and inst.particle_system is None and source.name in coll.all_objects:
        return source.name, None
    return None, (f"object {source.name!r} moves and is instanced by {instancer.name!r} (particles, vertices, faces, "
                  "geometry nodes or a nested collection); only a moving object directly in an instanced collection "
                  "is supported")


def _first(*reasons):
    return next((r for r in reasons if r), None)


@dataclass
class _Found:
    key: str
    name: str
    world: np.ndarray
    is_dyn: bool
    driver: str
    parent_world: np.ndarray | None
    source: str | None
    scenery: bool = False  # the object's (or its instancer's) ``buildee_scenery`` property (MeshPart.scenery)


def _instance(inst, scene, dynamic: set[str], memo: dict) -> tuple[_Found, str | None]:
    """An instance's description, and a refusal (or None) if its motion cannot be followed."""
    obj, parent = _original(inst.object), _original(inst.parent)
    pid = "-".join(str(i) for i in inst.persistent_id if i != 0x7FFFFFFF)
    source, refusal = _instance_motion(inst, obj, parent, dynamic, memo)
    psys = inst.particle_system
    if psys is not None and _particles_move(psys, scene):
        refusal = (f"the particles of {parent.name!r} ({psys.name}) move, appear or die during frames "
                   f"{scene.frame_start}-{scene.frame_end}; copies are taken once at load: use Physics 'None' "
                   "with every particle alive over those frames, or hair")
    found = _Found(instance_key(parent.name, obj.name, pid), obj.name, _matrix(inst.matrix_world),
                   parent.name in dynamic or source is not None, parent.name, _matrix(inst.parent.matrix_world), source,
                   bool(parent.get(SCENERY_PROPERTY) or obj.get(SCENERY_PROPERTY)))
    return found, refusal


def _simulated(inst, flags: _LayerFlags) -> bool:
    """The instance shows triangles to the render camera."""
    obj = inst.object
    if obj.type not in GEOMETRY_TYPES or not inst.show_self:
        return False
    if not inst.is_instance and _hidden_instancer_child(_original(obj)):
        return False
    return _camera_sees(inst, flags)


def _holdout(inst, flags: _LayerFlags) -> str | None:
    anchor = _anchor(inst)
    if anchor.name not in flags.holdout:
        return None
    return (f"object {anchor.name!r} is a holdout (Visibility > Holdout, or its collection's holdout in the view "
            "layer): the ground truth cannot show a hole; turn holdout off or disable the object in renders")


def extract_parts() -> ExtractedScene:
    """Parts of the current frame, sorted by a stable key (name; instances by instancer,
    name and persistent id). Static parts are baked into world coordinates."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene, flags = bpy.context.scene, _LayerFlags.of(bpy.context.view_layer)
    dynamic = dynamic_object_names()
    cache, memo, refusals, rendered, found = {}, {}, [], set(), []
    spawn = None
    for inst in depsgraph.object_instances:
        if not _simulated(inst, flags):
            continue
        if inst.is_instance:
            f, refusal = _instance(inst, scene, dynamic, memo)
            refusals.append(refusal)
        else:
            original = _original(inst.object)
            name = original.name
            f = _Found(object_key(name), name, _matrix(inst.matrix_world), name in dynamic, name, None, None,
                       bool(original.get(SCENERY_PROPERTY)))
        refusals.append(_holdout(inst, flags))
        verts, faces, closed, outward, reflectivity, transparent = _evaluated_mesh(inst.object, cache)
        if len(faces) == 0:
            continue
        refusals.append(_not_finite(f, verts))
        if label_of(f.name) == SPAWN_LABEL:
            wv = apply_affine(f.world, verts)  # BLAS-free: the same bits on every CPU
            c, o = closed_and_orientation(wv, faces)
            spawn = MeshPart(f.key, SPAWN_LABEL, wv, faces.copy(), closed=c, outward=o)
            continue
        rendered.add(_original(inst.object))
        found.append((f, verts, faces, closed, outward, reflectivity, transparent))

    if spawn is None:
        spawn = _hidden_spawn_volume()
    parts, bindings = _parts_of(sorted(found, key=lambda x: x[0].key), depsgraph)
    # this scene's objects (not other scenes' or orphans), hidden ones included: a keyed
    # hide_render may show them later; and what instancing brings in
    scene_objects = set(scene.objects) | rendered | {_original(i.parent) for i in depsgraph.object_instances if i.is_instance}
    shapes = [o for o in scene_objects if o.type in GEOMETRY_TYPES or o.type == "EMPTY"]  # not lights, cameras
    refusal = _first(*refusals, _shared_name(rendered), animated_visibility(shapes), deforming(rendered))
    return ExtractedScene(parts, bindings, spawn, refusal)


def _shared_name(objects) -> str | None:
    """A one-line refusal if two of the rendered ``objects`` have one name (a local object and
    one linked from a library can): the Simulator tells objects apart by their names."""
    seen = {}
    for obj in sorted(objects, key=lambda o: (o.name, o.library is not None)):
        first = seen.setdefault(obj.name, obj)
        if first != obj:
            where = [f"linked from {o.library.name!r}" if o.library else "of this file" for o in (first, obj)]
            return (f"two rendered objects are named {obj.name!r} ({where[0]}, {where[1]}); objects are told apart "
                    "by name: rename one (make the linked one local, or rename it in its library)")
    return None


def _not_finite(f: _Found, verts: np.ndarray) -> str | None:
    """A one-line refusal if an object's vertices or world matrix hold NaN or infinity."""
    if np.isfinite(f.world).all() and np.isfinite(verts).all():
        return None
    if not np.isfinite(verts).all():
        return (f"object {f.name!r} has NaN or infinite coordinates in its vertices (after its modifiers): fix or "
                "delete those vertices, or delete the object")
    return (f"object {f.name!r} has NaN or infinite coordinates in its world matrix (transform, parent or "
            "constraints): fix them, or delete the object")


def objects_by_name() -> dict:
    """Blender's objects by name, made once (``bpy.data.objects[name]`` searches them all;
    of two objects of one name, a local one and a linked one, the first, as that lookup does)."""
    table = {}
    for obj in bpy.data.objects:
        table.setdefault(obj.name, obj)
    return table


def _parts_of(found, depsgraph) -> tuple[list[MeshPart], list[DynamicBinding]]:
    parts, bindings = [], []
    objects = objects_by_name() if any(f.is_dyn for f, *_ in found) else {}
    for f, verts, faces, closed, outward, reflectivity, transparent in found:
        label = label_of(f.name)
        if f.is_dyn:
            source = objects[f.source] if f.source is not None else None
            offset = _offset(f.world, f.parent_world, source, depsgraph)
            bindings.append(DynamicBinding(len(parts), f.driver, offset, f.source, objects[f.driver], source))
            parts.append(MeshPart(f.key, label, verts.copy(), faces, True, f.world, closed, outward, f.name, f.scenery,
                                  reflectivity, transparent))
        else:
            wv = apply_affine(f.world, verts)  # BLAS-free: the same bits on every CPU
            if np.linalg.det(f.world[:3, :3]) < 0:
                outward = -outward  # a mirroring matrix flips the winding
            parts.append(MeshPart(f.key, label, wv, faces, False, np.eye(4), closed, outward, f.name, f.scenery,
                                  reflectivity, transparent))
    return parts, bindings


def _offset(world, parent_world, source, depsgraph) -> np.ndarray:
    """The constant of a binding: world = driver @ offset (@ source, a Blender object)."""
    if parent_world is None:
        return np.eye(4)
    offset = matmul_exact(affine_inverse(parent_world), world)
    if source is None:
        return offset
    moving = source.evaluated_get(depsgraph)
    return matmul_exact(offset, affine_inverse(_matrix(moving.matrix_world)))


def dynamic_matrices(bindings: list[DynamicBinding]) -> dict[int, np.ndarray]:
    """world_from_object of every dynamic part at the current frame."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = {}
    for b in bindings:
        obj = b.driver_object.evaluated_get(depsgraph)
        m = matmul_exact(_matrix(obj.matrix_world), b.offset)  # BLAS-free
        if b.source is not None:
            m = matmul_exact(m, _matrix(b.source_object.evaluated_get(depsgraph).matrix_world))
        out[b.part] = m
    return out


MAX_PASS_INDEX = 32767  # Blender's Object.pass_index is a short


def too_many_objects(count: int, where) -> str | None:
    """A one-line refusal if ``count`` objects need more pass indices than Blender has, else None."""
    if count <= MAX_PASS_INDEX:
        return None
    return (f"{where} has {count} objects, more than Blender's {MAX_PASS_INDEX} object pass indices (the Object "
            "Index pass numbers objects): join objects (Ctrl+J), delete unused ones, or split the scene")


@dataclass
class PassTable:
    """Object pass indices: ``labels[k]`` / ``instances[k]`` are the label id and part index
    of pass index k (entry 0, no object, is -1); ``of_part[i]`` is part i's pass index."""

    labels: np.ndarray
    instances: np.ndarray
    of_part: np.ndarray


def pass_index_owners(parts: list[MeshPart]) -> dict[str, int]:
    """Blender object name -> its first part, for the objects that need a pass index (those
    whose parts have faces; instanced copies share their object's)."""
    first_part: dict[str, int] = {}
    for i, p in enumerate(parts):
        if len(p.faces):
            first_part.setdefault(p.source, i)
    return first_part


def assign_pass_indices(parts: list[MeshPart], label_ids: dict[str, int]) -> PassTable:
    """Give every simulated Blender object a unique ``pass_index`` (1, 2, ...; 0 = none).

    Copies of one object made by instancing share its pass index and map to the first of
    those parts. A part with no faces (an object of a fixed instance table that this scene
    lacks) has no Blender object and pass index 0.
    """
    first_part = pass_index_owners(parts)
    refusal = too_many_objects(len(first_part), "the scene")
    if refusal:
        raise ValueError(refusal)
    for obj in bpy.data.objects:
        obj.pass_index = 0
    objects = objects_by_name()
    labels = np.full(len(first_part) + 1, -1, dtype=np.int32)
    instances = np.full(len(first_part) + 1, -1, dtype=np.int32)
    index_of_source = {}
    for k, (source, i) in enumerate(first_part.items(), start=1):
        objects[source].pass_index = k
        labels[k] = label_ids[parts[i].label]
        instances[k] = i
        index_of_source[source] = k
    of_part = np.array([index_of_source[p.source] if len(p.faces) else 0 for p in parts], dtype=np.int32)
    return PassTable(labels, instances, of_part)
