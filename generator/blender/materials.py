"""Blender node materials for generated sites, with seeded colour and roughness variation.

Each material is declared once, bpy-free (:class:`generator.scene.materials.Material`: the
shared ones in generator/scene/materials.py, each kind's own in its catalogue entry); this
module turns a declaration into a Principled BSDF node tree (:func:`make_material`)."""

from __future__ import annotations

import colorsys

import bpy
import numpy as np

from ..geometry.seeding import stream
from ..scene.kinds import all_materials
from ..scene.materials import DEFAULT
from .extract import REFLECTIVITY_PROPERTY, TRANSPARENT_PROPERTY



def _jitter(rgb, rng: np.random.Generator, hue=0.02, sat=0.1, val=0.12):
    h, s, v = colorsys.rgb_to_hsv(*rgb)
    h = (h + rng.uniform(-hue, hue)) % 1.0
    s = float(np.clip(s * (1 + rng.uniform(-sat, sat)), 0, 1))
    v = float(np.clip(v * (1 + rng.uniform(-val, val)), 0, 1))
    return colorsys.hsv_to_rgb(h, s, v)


def material_name(key: str) -> str:
    """The Blender name of the site material ``key``."""
    return f"site_{key}"


def make_material(key: str, seed: int):
    """The material ``key`` of this site's seed (created once per file): its colour and
    roughness jittered from the stream of (seed, "material", key), its texture layers as nodes."""
    name = material_name(key)
    if name in bpy.data.materials:
        return bpy.data.materials[name]
    recipes = all_materials()  # read now: a kind registered after this module's import has its materials
    recipe = recipes.get(key, recipes[DEFAULT])
    rng = stream(seed, "material", key)
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    bsdf = nodes.get("Principled BSDF") or nodes.new("ShaderNodeBsdfPrincipled")
    colour = _jitter(recipe.colour, rng)
    roughness = float(np.clip(recipe.roughness + rng.uniform(-0.1, 0.1), 0.02, 1.0))
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = recipe.metallic
    if recipe.roughness_range is not None:  # drawn per seed (the paper's ground)
        bsdf.inputs["Roughness"].default_value = float(rng.uniform(*recipe.roughness_range))
    if recipe.specular_range is not None:
        bsdf.inputs["Specular IOR Level"].default_value = float(rng.uniform(*recipe.specular_range))
    layers = recipe.patterns()
    if not layers:
        bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    else:
        mat.node_tree.links.new(_add_layers(mat.node_tree, layers, colour, rng, recipe.planar), bsdf.inputs["Base Color"])
    mat.diffuse_color = (*colour, 1.0)  # viewport / Workbench colour
    mat[REFLECTIVITY_PROPERTY] = float(recipe.lidar_reflectivity)  # what a LiDAR sees (generator/lidar/physics.py)
    mat[TRANSPARENT_PROPERTY] = bool(recipe.transparent)
    return mat


def _add_layers(tree, layers, colour, rng: np.random.Generator, planar: bool = False):
    """Each layer's texture (object coordinates: features per metre; in 2D when ``planar``)
    mixes the colour so far towards the layer's (jittered) colour; the last mix's output socket."""
    nodes, links = tree.nodes, tree.links
    coords = nodes.new("ShaderNodeTexCoord")
    current = None  # the colour so far: an output socket, or None for the base colour
    for layer in layers:
        fac = _layer_factor(nodes, links, coords.outputs["Object"], layer, rng, planar)
        mix = nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        weight = nodes.new("ShaderNodeMath")
        weight.operation = "MULTIPLY"
        links.new(fac, weight.inputs[0])
        weight.inputs[1].default_value = layer.strength
        links.new(weight.outputs[0], mix.inputs["Factor"])
        if current is None:
            mix.inputs["A"].default_value = (*colour, 1.0)
        else:
            links.new(current, mix.inputs["A"])
        mix.inputs["B"].default_value = (*_jitter(layer.colour, rng), 1.0)
        current = mix.outputs["Result"]
    return current


def _layer_factor(nodes, links, vector, layer, rng: np.random.Generator, planar: bool = False):
    """The layer's texture at ``vector`` (divided by its ``stretch`` along each axis) as a
    factor in [0, 1] (an output socket)."""
    scale = layer.scale * float(rng.uniform(0.8, 1.25))
    if tuple(layer.stretch) != (1.0, 1.0, 1.0):
        squash = nodes.new("ShaderNodeVectorMath")
        squash.operation = "MULTIPLY"
        links.new(vector, squash.inputs[0])
        squash.inputs[1].default_value = tuple(1.0 / k for k in layer.stretch)
        vector = squash.outputs["Vector"]
    return _TEXTURES[layer.kind](nodes, links, vector, layer, scale, planar)


def _voronoi(nodes, links, vector, layer, scale: float, planar: bool):
    """A stone at each cell: 1 at its centre, 0 at its edge, times its own shade."""
    tex = nodes.new("ShaderNodeTexVoronoi")
    tex.voronoi_dimensions = "2D" if planar else "3D"
    tex.inputs["Scale"].default_value = scale
    links.new(vector, tex.inputs["Vector"])
    ramp = nodes.new("ShaderNodeMapRange")
    ramp.inputs["From Min"].default_value, ramp.inputs["From Max"].default_value = 0.45, 0.1
    links.new(tex.outputs["Distance"], ramp.inputs["Value"])
    shade = nodes.new("ShaderNodeMath")
    shade.operation = "MULTIPLY"
    links.new(ramp.outputs["Result"], shade.inputs[0])
    links.new(tex.outputs["Color"], shade.inputs[1])
    return shade.outputs[0]


def _noise(nodes, links, vector, layer, scale: float, planar: bool):
    """Fractal noise, its middle half stretched to [0, 1]."""
    tex = nodes.new("ShaderNodeTexNoise")
    tex.noise_dimensions = "2D" if planar else "3D"
    tex.inputs["Scale"].default_value = scale
    tex.inputs["Detail"].default_value = layer.detail
    links.new(vector, tex.inputs["Vector"])
    ramp = nodes.new("ShaderNodeMapRange")
    ramp.inputs["From Min"].default_value, ramp.inputs["From Max"].default_value = 0.35, 0.65
    links.new(tex.outputs["Fac"], ramp.inputs["Value"])
    return ramp.outputs["Result"]


def _courses(nodes, links, vector, layer, scale: float, planar: bool):
    """1 on the joints of a running bond, 0 on the units: Blender's brick texture on (x + y, z),
    so a vertical face along either object axis shows courses of 1 / ``layer.scale`` metres
    (the drawn scale only shifts the bond, within 5%: brick and panel sizes are standards)."""
    height = 1.0 / (layer.scale * (1.0 + 0.2 * (scale / layer.scale - 1.0)))  # the drawn jitter, 5x smaller
    split = nodes.new("ShaderNodeSeparateXYZ")
    links.new(vector, split.inputs["Vector"])
    along = nodes.new("ShaderNodeMath")
    along.operation = "ADD"
    links.new(split.outputs["X"], along.inputs[0])
    links.new(split.outputs["Y"], along.inputs[1])
    plane = nodes.new("ShaderNodeCombineXYZ")
    links.new(along.outputs[0], plane.inputs["X"])
    links.new(split.outputs["Z"], plane.inputs["Y"])
    tex = nodes.new("ShaderNodeTexBrick")
    tex.offset, tex.offset_frequency = 0.5, 2
    links.new(plane.outputs["Vector"], tex.inputs["Vector"])
    tex.inputs["Scale"].default_value = 1.0
    tex.inputs["Row Height"].default_value = height
    tex.inputs["Brick Width"].default_value = height * layer.aspect
    tex.inputs["Mortar Size"].default_value = height * layer.joint
    tex.inputs["Mortar Smooth"].default_value = 0.1
    return tex.outputs["Fac"]


_TEXTURES = {"noise": _noise, "voronoi": _voronoi, "courses": _courses}
