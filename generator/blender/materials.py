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
    """The material ``key`` of this site's seed (created once per file)."""
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
        _add_layers(mat, bsdf, layers, colour, rng)
    mat.diffuse_color = (*colour, 1.0)  # viewport / Workbench colour
    return mat


def _add_layers(mat, bsdf, layers, colour, rng: np.random.Generator) -> None:
    """Each layer's texture (object coordinates: features per metre) mixes the colour so far
    towards the layer's (jittered) colour."""
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    coords = nodes.new("ShaderNodeTexCoord")
    current = None  # the colour so far: an output socket, or None for the base colour
    for layer in layers:
        fac = _layer_factor(nodes, links, coords.outputs["Object"], layer, rng)
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
    links.new(current, bsdf.inputs["Base Color"])


def _layer_factor(nodes, links, vector, layer, rng: np.random.Generator):
    """The layer's texture at ``vector`` as a factor in [0, 1] (an output socket)."""
    scale = layer.scale * float(rng.uniform(0.8, 1.25))
    ramp = nodes.new("ShaderNodeMapRange")
    if layer.kind == "voronoi":  # a stone at each cell: 1 at its centre, 0 at its edge, times its own shade
        tex = nodes.new("ShaderNodeTexVoronoi")
        tex.inputs["Scale"].default_value = scale
        links.new(vector, tex.inputs["Vector"])
        ramp.inputs["From Min"].default_value, ramp.inputs["From Max"].default_value = 0.45, 0.1
        links.new(tex.outputs["Distance"], ramp.inputs["Value"])
        shade = nodes.new("ShaderNodeMath")
        shade.operation = "MULTIPLY"
        links.new(ramp.outputs["Result"], shade.inputs[0])
        links.new(tex.outputs["Color"], shade.inputs[1])
        return shade.outputs[0]
    tex = nodes.new("ShaderNodeTexNoise")
    tex.inputs["Scale"].default_value = scale
    tex.inputs["Detail"].default_value = layer.detail
    links.new(vector, tex.inputs["Vector"])
    ramp.inputs["From Min"].default_value, ramp.inputs["From Max"].default_value = 0.35, 0.65
    links.new(tex.outputs["Fac"], ramp.inputs["Value"])
    return ramp.outputs["Result"]
