"""Small Blender scenes built in code for the tests (imports bpy)."""

from __future__ import annotations

import math
from pathlib import Path

import bpy

from generator.blender import session


def new_scene(width: int = 64, height: int = 48) -> None:
    session.new_empty_file()
    scene = bpy.context.scene
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.frame_start, scene.frame_end = 1, 50
    scene.frame_set(1)
    # Cycles at one sample, not the factory file's EEVEE: on a machine without a GPU, EEVEE
    # renders on a software OpenGL (30-40 s for 64x48); tests that want another engine set it
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False


def add_box(name: str, size, location, rotation=(0.0, 0.0, 0.0)):
    """An axis-aligned box (closed mesh) of ``size`` (sx, sy, sz) centred at ``location``."""
    sx, sy, sz = (s / 2 for s in size)
    verts = [(x, y, z) for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return _object(name, verts, faces, location, rotation)


def add_plane(name: str, size, location, rotation=(0.0, 0.0, 0.0)):
    """A single-sided rectangle (open mesh) of ``size`` (sx, sy) in its local XY plane."""
    sx, sy = size[0] / 2, size[1] / 2
    verts = [(-sx, -sy, 0), (sx, -sy, 0), (sx, sy, 0), (-sx, sy, 0)]
    return _object(name, verts, [(0, 1, 2, 3)], location, rotation)


def add_cylinder(name: str, radius: float, depth: float, location, rotation=(0.0, 0.0, 0.0), segments: int = 32):
    """A closed cylinder along its local Z axis."""
    verts, faces = [], []
    for k in range(segments):
        a = 2 * math.pi * k / segments
        verts += [(radius * math.cos(a), radius * math.sin(a), -depth / 2), (radius * math.cos(a), radius * math.sin(a), depth / 2)]
    for k in range(segments):
        k2 = (k + 1) % segments
        faces.append((2 * k, 2 * k2, 2 * k2 + 1, 2 * k + 1))
    faces.append(tuple(2 * k for k in reversed(range(segments))))
    faces.append(tuple(2 * k + 1 for k in range(segments)))
    return _object(name, verts, faces, location, rotation)


def _object(name, verts, faces, location, rotation):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.view_layer.update()
    return obj


def add_camera(location, rotation_euler, lens: float = 35.0, name: str = "Camera"):
    """A perspective camera; Blender rotation (1.5708, 0, 0) looks along +Y."""
    data = bpy.data.cameras.new(name)
    data.lens = lens
    cam = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(cam)
    cam.location = location
    cam.rotation_euler = rotation_euler
    bpy.context.scene.camera = cam
    bpy.context.view_layer.update()
    return cam


def look_along_y(location, lens: float = 35.0):
    """Camera at ``location`` looking along world +Y, level."""
    return add_camera(location, (math.pi / 2, 0.0, 0.0), lens)


def save(path: Path) -> Path:
    session.save_blend(path)
    return path


def walls_scene(path: Path, width: int = 64, height: int = 48) -> Path:
    """Ground plane, a wall 5 m ahead of a camera at (0, 0, 1.5) looking along +Y."""
    new_scene(width, height)
    add_plane("Ground", (60, 60), (0, 10, 0))
    add_box("Wall", (4, 0.2, 3), (0, 5, 1.5))
    add_box("Crate", (1, 1, 1), (3, 8, 0.5))
    add_box("Crate.001", (1, 1, 1), (-3, 8, 0.5))
    look_along_y((0, 0, 1.5))
    return save(path)


def add_sun(strength: float = 3.0, rotation=(0.6, 0.2, 0.8)):
    data = bpy.data.lights.new("Sun", "SUN")
    data.energy = strength
    sun = bpy.data.objects.new("Sun", data)
    bpy.context.scene.collection.objects.link(sun)
    sun.rotation_euler = rotation
    world = bpy.data.worlds.new("World")
    world.color = (0.4, 0.5, 0.7)
    bpy.context.scene.world = world
    return sun


def make_linear(obj) -> None:
    """Linear interpolation between all keyframes of ``obj`` (constant speed)."""
    from bpy_extras import anim_utils

    ad = obj.animation_data
    for fc in anim_utils.action_get_channelbag_for_slot(ad.action, ad.action_slot).fcurves:
        for key in fc.keyframe_points:
            key.interpolation = "LINEAR"


TILTED_PLANE_SIZE = (80, 60)  # (width, height) in pixels of tilted_plane_scene


def tilted_plane_scene(path: Path) -> Path:
    """A large plane ("Board") through (0, 10, 0), tilted 30 degrees about X and 20 about Z, seen
    by a level camera at the origin looking along +Y; a crate and a thin pole in front of it."""
    new_scene(*TILTED_PLANE_SIZE)
    add_plane("Board", (200, 200), (0, 10, 0), rotation=(math.radians(90 - 30), 0, math.radians(20)))
    add_box("Crate", (1.5, 1.5, 1.5), (1.2, 6, -0.8))
    add_cylinder("Pole", 0.03, 6, (-1.0, 5, 0), segments=12)
    add_sun()
    look_along_y((0, 0, 0), lens=30)
    return save(path)
