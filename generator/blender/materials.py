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
from ..scene.materials import DEFAULT, Material

RECIPES: dict[str, Material] = all_materials()  # every declared material by name (generator/scene/materials.py)


def _jitter(rgb, rng: np.random.Generator, hue=0.02, sat=0.1, val=0.12):
    h, s, v = colorsys.rgb_to_hsv(*rgb)
    h = (h + rng.uniform(-hue, hue)) % 1.0
    s = float(np.clip(s * (1 + rng.uniform(-sat, sat)), 0, 1))
    v = float(np.clip(v * (1 + rng.uniform(-val, val)), 0, 1))
    return colorsys.hsv_to_rgb(h, s, v)


def make_material(key: str, seed: int):
    """The material ``key`` of this site's seed (created once per file)."""
    name = f"site_{key}"
    if name in bpy.data.materials:
        return bpy.data.materials[name]
    recipe = RECIPES.get(key, RECIPES[DEFAULT])
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
    if recipe.pattern is None:
        bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    else:
        _add_pattern(mat, bsdf, recipe, colour, rng)
    mat.diffuse_color = (*colour, 1.0)  # viewport / Workbench colour
    return mat


def _add_pattern(mat, bsdf, recipe: Material, colour, rng: np.random.Generator) -> None:
    """The recipe's pattern: a noise texture mixing the base ``colour`` towards the
    pattern's (jittered) colour, into the BSDF's base colour."""
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexNoise")
    tex.inputs["Scale"].default_value = recipe.pattern.scale * float(rng.uniform(0.8, 1.25))
    tex.inputs["Detail"].default_value = 6.0
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs["Factor"].default_value = recipe.pattern.strength
    ramp = nodes.new("ShaderNodeMapRange")
    ramp.inputs["From Min"].default_value = 0.35
    ramp.inputs["From Max"].default_value = 0.65
    links.new(tex.outputs["Fac"], ramp.inputs["Value"])
    links.new(ramp.outputs["Result"], mix.inputs["Factor"])
    mix.inputs["A"].default_value = (*colour, 1.0)
    mix.inputs["B"].default_value = (*_jitter(recipe.pattern.colour, rng), 1.0)
    links.new(mix.outputs["Result"], bsdf.inputs["Base Color"])
