"""Turn the evaluated Blender scene into rigid mesh parts (numpy), with labels and motion.

Every render-visible object instance that yields triangles (meshes, curves, text, metaballs;
modifiers, geometry nodes and instancing evaluated) becomes one :class:`MeshPart`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import bpy
import numpy as np

from ..geometry.camera import affine_inverse, apply_affine, matmul_exact
from ..geometry.parts import MeshPart, closed_and_orientation
from .animation import dynamic_object_names

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
SPAWN_LABEL = "CameraSpawn"
_SUFFIX = re.compile(r"\.\d{3,}$")


def label_of(name: str) -> str:
    """Semantic label of an object: its name without Blender's ``.NNN`` duplicate suffix."""
    return _SUFFIX.sub("", name)


@dataclass
class DynamicBinding:
    """How to recompute a dynamic part's matrix at another frame.

    world_from_object(t) = world(driver, t) @ offset, where ``driver`` is the object whose
    evaluated matrix moves the part (the object itself, or the instancer of an instance).
    """

    part: int
    driver: str
    offset: np.ndarray


def _mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    nv = len(mesh.vertices)
    co = np.empty(nv * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", co)
    mesh.calc_loop_triangles()
    nt = len(mesh.loop_triangles)
    tri = np.empty(nt * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tri)
    return co.reshape(nv, 3), tri.reshape(nt, 3)


def _evaluated_mesh(obj, cache: dict):
    """(vertices, faces, closed, outward) of an evaluated object, cached per mesh datablock."""
    data = obj.data
    key = data.as_pointer() if (obj.type == "MESH" and data is not None) else None
    if key is not None and key in cache:
        return cache[key]
    if obj.type == "MESH":
        verts, faces = _mesh_arrays(data)
    else:
        mesh = obj.to_mesh()
        try:
            verts, faces = _mesh_arrays(mesh) if mesh is not None else (np.zeros((0, 3)), np.zeros((0, 3), np.int32))
        finally:
            obj.to_mesh_clear()
    closed, outward = closed_and_orientation(verts, faces) if len(faces) else (False, 1)
    result = (verts, faces, closed, outward)
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
            verts, faces = _mesh_arrays(obj.data)
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


def extract_parts() -> ExtractedScene:
    """Parts of the current frame, sorted by a stable key (name; instances by instancer,
    name and persistent id). Static parts are baked into world coordinates."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    dynamic = dynamic_object_names()
    cache: dict = {}
    found = []
    spawn = None
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type not in GEOMETRY_TYPES:
            continue
        if inst.is_instance:
            if not inst.show_self:
                continue
            parent = inst.parent
            name = obj.original.name if obj.original is not None else obj.name
            pid = "-".join(str(i) for i in inst.persistent_id if i != 0x7FFFFFFF)
            key = f"{parent.name}/{name}#{pid}"
            driver = parent.original.name if parent.original is not None else parent.name
            is_dyn = driver in dynamic
            parent_world = _matrix(parent.matrix_world)
        else:
            if not inst.show_self:
                continue
            name = obj.original.name if obj.original is not None else obj.name
            key, driver = name, name
            is_dyn = name in dynamic
            parent_world = None
        world = _matrix(inst.matrix_world)
        verts, faces, closed, outward = _evaluated_mesh(obj, cache)
        if len(faces) == 0:
            continue
        label = label_of(name)
        if label == SPAWN_LABEL:
            wv = apply_affine(world, verts)  # BLAS-free: the same bits on every CPU
            c, o = closed_and_orientation(wv, faces)
            spawn = MeshPart(key, label, wv, faces.copy(), closed=c, outward=o)
            continue
        found.append((key, label, verts, faces, closed, outward, world, is_dyn, driver, parent_world, name))

    if spawn is None:
        spawn = _hidden_spawn_volume()
    found.sort(key=lambda f: f[0])
    parts, bindings = [], []
    for key, label, verts, faces, closed, outward, world, is_dyn, driver, parent_world, source in found:
        if is_dyn:
            offset = matmul_exact(affine_inverse(parent_world), world) if parent_world is not None else np.eye(4)
            bindings.append(DynamicBinding(len(parts), driver, offset))
            parts.append(MeshPart(key, label, verts.copy(), faces, True, world, closed, outward, source))
        else:
            wv = apply_affine(world, verts)  # BLAS-free: the same bits on every CPU
            if np.linalg.det(world[:3, :3]) < 0:
                outward = -outward  # a mirroring matrix flips the winding
            parts.append(MeshPart(key, label, wv, faces, False, np.eye(4), closed, outward, source))
    return ExtractedScene(parts, bindings, spawn)


def dynamic_matrices(bindings: list[DynamicBinding]) -> dict[int, np.ndarray]:
    """world_from_object of every dynamic part at the current frame."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = {}
    for b in bindings:
        obj = bpy.data.objects[b.driver].evaluated_get(depsgraph)
        out[b.part] = matmul_exact(_matrix(obj.matrix_world), b.offset)  # BLAS-free
    return out


MAX_PASS_INDEX = 32767  # Blender's Object.pass_index is a short


@dataclass
class PassTable:
    """Object pass indices: ``labels[k]`` / ``instances[k]`` are the label id and part index
    of pass index k (entry 0, no object, is -1); ``of_part[i]`` is part i's pass index."""

    labels: np.ndarray
    instances: np.ndarray
    of_part: np.ndarray


def assign_pass_indices(parts: list[MeshPart], label_ids: dict[str, int]) -> PassTable:
    """Give every simulated Blender object a unique ``pass_index`` (1, 2, ...; 0 = none).

    Copies of one object made by instancing share its pass index and map to the first of
    those parts. A part with no faces (an object of a fixed instance table that this scene
    lacks) has no Blender object and pass index 0.
    """
    first_part: dict[str, int] = {}
    for i, p in enumerate(parts):
        if len(p.faces):
            first_part.setdefault(p.source, i)
    if len(first_part) > MAX_PASS_INDEX:
        raise ValueError(f"{len(first_part)} objects exceed Blender's {MAX_PASS_INDEX} object pass indices")
    for obj in bpy.data.objects:
        obj.pass_index = 0
    labels = np.full(len(first_part) + 1, -1, dtype=np.int32)
    instances = np.full(len(first_part) + 1, -1, dtype=np.int32)
    index_of_source = {}
    for k, (source, i) in enumerate(first_part.items(), start=1):
        bpy.data.objects[source].pass_index = k
        labels[k] = label_ids[parts[i].label]
        instances[k] = i
        index_of_source[source] = k
    of_part = np.array([index_of_source[p.source] if len(p.faces) else 0 for p in parts], dtype=np.int32)
    return PassTable(labels, instances, of_part)
